"""Numba kernels, split by job; importing this package compiles nothing.

- ``layout``: codes and the columns of the kernels' arrays (plain Python, no numba):
  what the grid builder writes and the Dataset constructor reads.
- ``stack``: fixed-size scratch arrays on the stack, for kernels of one small state size.
- ``equations``: the log-form right-hand side, its analytic Jacobian, and the
  Jacobian's products the tangent needs.
- ``linalg``: dense LU factors and solves of the implicit method (``rosenbrock``).
- ``step``: the step record the loop hands on and the interpolant read from it.
- ``control``: the step-size controller of the adaptive methods.
- ``tangent``: the tangent vector and the largest Lyapunov exponent (Benettin et al.).
- ``methods``: the integration methods, one module each, and the registry mapping the
  config's names (``sweep/codes.py``, ``METHODS``) to them.
- ``classify``: the cycle classifier, split by job (its state, the per-step extrema,
  the per-cycle and end-of-run verdicts, the result row).
- ``record``: the recorder of traces.
- ``slip_events``: the catalogue of slip events of a run, written as it goes.
- ``integrate``: the per-variant grid kernel, the integration loop.
- ``monodromy``: the monodromy matrix of a periodic run (every tangent direction once
  around its cycle), from which ``engine/floquet.py`` takes the Floquet multipliers.

(``tests/test_docstrings.py`` checks that this list names every module and method.)

Only jitted loops live here; the equations are documented in ``sweep/model/physics.py``.
Everything a kernel needs is passed as an argument: numba's cache freezes globals,
so module-level names are true constants.
"""

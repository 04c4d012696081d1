"""Numba kernels, split by job; importing this package compiles nothing.

- ``layout``: codes and the columns of the kernels' arrays (plain Python, no numba):
  what the grid builder writes and the Dataset constructor reads.
- ``equations``: the log-form right-hand side, its analytic Jacobian, and the
  Jacobian's products the tangent needs.
- ``steppers``: the four methods' steps (RK4, DOPRI5, DOP853 and RODAS4,
  ``integrator.method`` ``rk4``, ``dopri5``, ``dop853`` and ``rosenbrock``) and their
  dense output.
- ``tableau_dop853``: DOP853's coefficients (Hairer's ``dop853.f``).
- ``cycles``: the cycle classifier (per-cycle statistics, return-map verdicts).
- ``tangent``: the tangent vector and the largest Lyapunov exponent (Benettin et al.).
- ``integrate``: the integration loop of one system and the per-variant grid kernel.
- ``stack``: fixed-size scratch arrays on the stack, for kernels of one small state size.

(``tests/test_docstrings.py`` checks that this list names every module and method.)

Only jitted loops live here; the equations are documented in ``sweep/physics.py``.
Everything a kernel needs is passed as an argument: numba's cache freezes globals,
so module-level names are true constants.
"""

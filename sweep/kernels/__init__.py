"""Numba kernels, split by job; importing this package compiles nothing.

- ``layout``: codes and the columns of the kernels' arrays (plain Python, no numba):
  what the grid builder writes and the Dataset constructor reads.
- ``equations``: the log-form right-hand side and its analytic Jacobian.
- ``steppers``: RK4, DOPRI5 and RODAS4 steps and their dense output.
- ``cycles``: the cycle classifier (per-cycle statistics, return-map verdicts).
- ``integrate``: the integration loop of one system and the per-variant grid kernel.
- ``stack``: fixed-size scratch arrays on the stack, for kernels of one small state size.

Only jitted loops live here; the equations are documented in ``sweep/physics.py``.
Everything a kernel needs is passed as an argument: numba's cache freezes globals,
so module-level names are true constants.
"""

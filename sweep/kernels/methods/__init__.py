"""The integration methods, one module each; the registry maps a method's config name
and code to its module.

The registry is ``METHODS`` in ``sweep/codes.py`` (config name → module here; a
method's code is its place there): adding a method is a module here and a line there.
Each module states, as module-level names the grid kernel reads when it is built
(``kernels/integrate.py``; numba takes them as constants):

- ``NAME``: the method's own name; ``ADAPTIVE``: whether it controls its error (else
  it takes the fixed step ``P_DT``); ``EXPONENT``: its controller's exponent −1/(q+1),
  q the order of its error estimate (``control.next_step_size``).
- ``STAGE_ROWS``: rows of its stage scratch ``k`` (n columns); ``MATRIX``: whether it
  needs a matrix and n pivots (``mat``, ``perm``), and then ``matrix_columns(model,
  coupling)`` (plain Python, codes): the columns of its n rows (0: n, the dense n × n).
- ``step(y, f, h, p, model, law, coupling, het, nb, ev, k, mat, perm, ytmp, ynew, fnew,
  rtol, atol)``: one step from y (slope f) into ynew (slope fnew); returns its error
  norm (acceptable when ≤ 1; 0 for a fixed-step method).
- ``DENSE_ROWS``: the coefficients r5 … of its interpolant beyond the cubic (0: the
  cubic Hermite interpolant); ``DENSE_STAGES``: the right-hand-side evaluations they
  cost; ``dense(y, f, h, p, model, law, coupling, het, nb, ev, k, ytmp, fnew, dense)``:
  writes them into rows 0 … of ``dense`` (``step.Step``). ``EXCURSION``: the bound its
  interpolant's extrema obey (``step.PROVED`` or ``step.MEASURED``; a method whose
  coefficients cost stages needs one that reads none, ``MEASURED``).
- ``TANGENT_ROWS``: rows of the tangent's stage scratch; ``TANGENT_CAP``: whether its
  step is capped while the tangent is carried (``tangent.TANGENT_TURN``);
  ``tangent_step(y, f, h, k, mat, perm, delta, work, dk, blocks, p, nb, ev, model, law,
  coupling, het)``: carries the tangent over the step just taken, the exact derivative
  of the step from its stages (an explicit method passes its tableau to
  ``tangent.explicit_tangent_step``).

Functions of the loop's hot path (``step``, ``dense`` where it costs no stage) are
inlined into it (``accelerate.jit_inline``).
"""

from importlib import import_module

from ...codes import METHODS
from ..step import MEASURED

#: The module of each method, in code order (``layout.S_METHOD``).
MODULES = tuple(import_module(f"{__name__}.{module}") for module in METHODS.values())

for _m in MODULES:
    if _m.DENSE_STAGES and _m.EXCURSION != MEASURED:
        raise ImportError(f"{_m.__name__}: coefficients that cost stages need step.MEASURED")

"""The step-size controller of the adaptive methods (a fixed-step method keeps its step)."""

import math

from ..accelerate import jit_inline


@jit_inline
def next_step_size(exponent, h, err, max_step):
    """The step after one of size ``h`` with error norm ``err`` (D0/V): the standard
    controller 0.9 err^exponent, the method's ``EXPONENT`` = −1/(q+1) (q: the order of
    its error estimate), growing at most 5× and at most to ``max_step`` after an
    accepted step, shrinking at least 5× after a rejected one (and 5× when the error is
    not finite).

    Tried and not kept (``docs/internals.md``): a PI controller, no growth right after
    a rejection, growth up to 10×, and Gustafsson's predictive controller, which cut
    rejected steps but changed every number and moved labels.
    """
    if err <= 1.0:
        return min(max_step, h * min(5.0, 0.9 * max(err, 1e-10) ** exponent))
    if math.isfinite(err):
        return h * max(0.2, 0.9 * err**exponent)
    return h * 0.2

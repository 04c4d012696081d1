"""The recorder of traces: the state at the multiples of a time step, read from each
step record's interpolant, and at the start and end of a run."""

from ..accelerate import jit
from .step import dense_tail, dense_value


@jit
def record_start(y, rec_t, rec_y):
    """Record the initial state when there are buffers; returns the count."""
    if rec_t.size == 0:
        return 0
    rec_t[0] = 0.0
    for j in range(y.size):
        rec_y[0, j] = y[j]
    return 1


@jit
def record_step(s, t, h, rec_dt, rec_t, rec_y, n_rec):
    """Record the state at the multiples of ``rec_dt`` inside the step ``s`` from ``t`` to
    ``t + h`` (its interpolant) while the buffers have room (the last slot is kept for
    the end). Returns the count."""
    rec_cap = rec_t.size
    y, ynew, f, fnew = s.y, s.ynew, s.f, s.fnew
    while n_rec < rec_cap - 1 and n_rec * rec_dt <= t + h and rec_dt > 0.0:
        theta = (n_rec * rec_dt - t) / h
        rec_t[n_rec] = n_rec * rec_dt
        for j in range(y.size):
            r = dense_tail(s, j)
            rec_y[n_rec, j] = dense_value(y[j], ynew[j], f[j], fnew[j], h, r, theta)
        n_rec += 1
    return n_rec


@jit
def record_end(t, y, rec_t, rec_y, n_rec):
    """Record the final state when the buffers have room; returns the count."""
    if 0 < n_rec < rec_t.size and rec_t[n_rec - 1] < t:
        rec_t[n_rec] = t
        for j in range(y.size):
            rec_y[n_rec, j] = y[j]
        n_rec += 1
    return n_rec

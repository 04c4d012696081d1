"""The cycle classifier, split by job (imports run down this list):

- ``state``: the classifier's arrays, their rows and columns, the start of a cycle.
- ``sequences``: the return-map verdicts of the cycle-to-cycle sequences.
- ``extrema``: per-step extremum tracking from the step record (``step.Step``).
- ``cycle``: the end of a cycle at each event, and its verdict.
- ``verdicts``: a run's regime and attractor at its end.
- ``result``: a run's statistics into its row of the results array.

An *event* is a maximum of ℓ_0 (ln v/V of block 0); a *cycle* of the classifier runs
from one event to the next. Each run keeps running statistics over the current cycle
and the last ``state.HISTORY`` completed ones, so memory does not depend on run length.
"""

"""
Phase diagram of one block
==========================

Sweep the driving stiffness K/W of the paper's one-block system (the packaged example
``oneblock``) across the critical stiffness Kc/W = (B − A)/D0 = 0.05 µm⁻¹, classify
each run and draw the phase diagram. The grid is small and the runs short, so that
the example takes seconds.
"""

import sweep

config = sweep.with_changes(
    "oneblock",
    {"sweep": {"K_W": {"start": 0.035, "stop": 0.06, "num": 6}}, "integrator": {"t_end": 500}},
)
ds = sweep.run(config, progress=False)
print(ds["regime"].attrs["flag_meanings"])
print(ds["regime"].values)

# %%
# ``sweep.plot_result`` returns a matplotlib Figure: the regime of every run against
# K/W, with the analytic Kc marked.
fig = sweep.plot_result(ds)
fig

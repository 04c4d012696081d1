"""
Phase boundaries by refinement
==============================

A phase diagram's content is its boundaries. Instead of a fine grid, run a coarse one
and refine it where the label of the runs (regime, attractor, number of events per
cycle) changes: every cell whose corner runs differ is split in two along each axis,
and only the new points are run, level by level. Here two unequal radiation-damped
blocks (the packaged example ``unequal_qd``) on a corner of their map, where steady
sliding, simple stick-slip cycles and cycles of two events meet, refined 4 levels.
"""

import sweep

config = sweep.with_changes(
    "unequal_qd",
    {
        "sweep": {
            "K_W": {"start": 0.05, "stop": 0.07, "num": 5},
            "k2_W": {"start": 0.005, "stop": 0.02, "num": 4},
        },
        "refine": {"levels": 4},
    },
)
ds = sweep.run(config, progress=False)
print("runs per level:", ds.attrs["refine_runs"])
print("a uniform grid of the finest cells:", (4 * 16 + 1) * (3 * 16 + 1), "runs")

# %%
# The runs lie along one dimension, ``point``, with the swept parameters and the level
# of each run as coordinates. ``sweep.plot_result`` draws the cells at their level,
# coloured by the attractor of their runs, and the boundaries between labels.
fig = sweep.plot_result(ds)
fig

# %%
# ``sweep.boundaries`` returns each boundary as a polyline in parameter space, with the
# size of the cell each segment crosses: how well that piece is known.
for b in sweep.boundaries(ds):
    size = ", ".join(f"{s:.2g}" for s in b.resolution.max(axis=0))
    print(f"{' | '.join(b.between)}: {len(b.vertices)} vertices, cells up to {size} um^-1")

# %%
# ``sweep.to_grid`` puts the runs on the regular grid of any level (each grid point the
# value of the run of its cell), where every grid figure and xarray operation works.
grid = sweep.to_grid(ds, 3)
fig = sweep.plot_variable(grid, "period")
fig

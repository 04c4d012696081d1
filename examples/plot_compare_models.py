"""
Radiation damping turns the runaway into stick-slip
===================================================

Below Kc the quasi-static model has no stick-slip cycle: the slip velocity runs away.
With radiation damping (``model: quasi-dynamic``) the same systems settle on bounded
cycles. Both sweeps share one K/W axis; the bifurcation view compares them, and since
fixed parameters are coordinates, the results combine along the damping η/W
(η/W = 0.01 s/µm: η̂ = ηV/W = 0.001, Kc/W = 0.049 µm⁻¹).
"""

import xarray as xr

import sweep

config = sweep.with_changes(
    "oneblock",
    {"sweep": {"K_W": {"start": 0.035, "stop": 0.06, "num": 6}}, "integrator": {"t_end": 500}},
)
ds = sweep.run(config, progress=False)
damped = sweep.with_changes(
    config, {"name": "damped", "model": "quasi-dynamic", "parameters": {"eta_W": 0.01}}
)
qd = sweep.run(damped, progress=False)

# %%
# The amplitude of each attractor against each model's own K/Kc.
fig = sweep.plot_bifurcation([ds, qd])
fig

# %%
# The largest slip velocity of the damped cycles.
fig_v_max = sweep.plot_variable(qd, "v_max")
fig_v_max

# %%
# Fixed parameters are coordinates, so the two results combine along η/W.
both = xr.concat(
    [ds.assign_coords(eta_W=0.0), qd], dim="eta_W", coords="minimal", compat="override"
)
print(dict(both["regime"].sizes), "stick-slip runs:", int((both["regime"] == 1).sum()))

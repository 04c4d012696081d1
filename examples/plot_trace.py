r"""
One system in time: a stick-slip cycle
======================================

A phase diagram labels each grid point; a trace shows one of them in time. Pin every
sweep axis (here K/W = 0.046 µm⁻¹, K/Kc = 0.94 with radiation damping η/W = 0.01
s/µm) and integrate that one system: the result is a Dataset with the velocity,
:math:`\ln(v/V)`, :math:`\ln(\Phi/\Phi_{ss})` and friction of each block against time
(s), and the run's regime and statistics as attributes.
"""

import sweep
from sweep import compute_trace, pin_config

config = sweep.with_changes("oneblock", {"model": "quasi-dynamic", "parameters": {"eta_W": 0.01}})
# the first 300 D0/V (3000 s): the oscillation grows onto its cycle
trace = compute_trace(pin_config(config, {"K_W": 0.046}, 300), points=2000)
print(trace.attrs["regime"], f"period {trace.attrs['period']:.1f} s")
print(list(trace.data_vars))

# %%
# ``sweep.plot_trace`` draws the time series; the time axis ends where the run ended.
fig = sweep.plot_trace(trace)
fig

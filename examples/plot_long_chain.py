"""
Slip events of a long chain
===========================

A chain of many blocks slips in events of many sizes. Give a config a ``catalogue``
section and each run keeps its slip events (when, where they began, how many blocks
slipped, their summed slip, peak velocity) along a ``slip_event`` dimension, with
their statistics, each only where it applies: the Gutenberg–Richter b-value where
the law passes its goodness-of-fit test with enough events over a magnitude unit
(else NaN, and ``b_value_status`` says why), the share and recurrence of the
system-wide events (extent ≥ 0.9 of the chain; recurrence from ten intervals on).
Here the packaged ``long_chain`` (100 inertial blocks, ``rosenbrock-structured``) is
cut to 24 blocks, one coupling, two disorders of one seed and 1000 D0/V, so that the example
takes seconds: too few events for a b-value, as the status says.
"""

import sweep

config = sweep.with_changes(
    "long_chain",
    {
        "blocks": 24,
        "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.05},
        "sweep": {"k2_W": [0.3], "spread_D0": [0.0, 0.3], "spread_seed": [1]},
        "integrator": {"t_end": 1000.0},
        "catalogue": {"after": 0.2},
    },
)
ds = sweep.run(config, progress=False)
print(ds["slip_event_count"].values)  # events after the transient, per run
print(ds["system_wide_fraction"].values)  # fraction spanning at least 0.9 of the blocks
status = ds["b_value_status"]
print([status.attrs["flag_meanings"].split()[c] for c in status.values.ravel()])

# %%
# ``sweep.plot_catalogue`` draws one run: each event a bar over the blocks it spanned
# from its start to its end, coloured by its magnitude (2/3) log10(slip/D0), beside
# the number of events of at least each magnitude, with the Gutenberg–Richter fit and
# its truncated form only where they hold (else the reason in their place). The
# title states every fixed setting, the dimensionless mass M̂ = mV²/(W D0) and the
# largest v_max/V: slow slip here, not earthquakes.
fig = sweep.plot_catalogue(ds, {"k2_W": 0.3, "spread_D0": 0.3})
fig

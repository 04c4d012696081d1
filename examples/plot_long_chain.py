"""
Slip events of a long chain
===========================

A chain of many blocks has earthquakes of many sizes. Give a config a ``catalogue``
section and each run keeps its slip events (when, where they began, how many blocks
slipped, their summed slip, peak velocity) along a ``slip_event`` dimension, with
their statistics: the b-value, the recurrence of the events that rupture the whole
chain, and the fraction of them. Here the packaged ``long_chain`` (100 inertial
blocks, ``rosenbrock-structured``) is cut to 24 blocks and one coupling, two
disorders and 1000 D0/V, so that the example takes seconds.
"""

import sweep

config = sweep.with_changes(
    "long_chain",
    {
        "blocks": 24,
        "initial": {"v_over_V": 1.0, "phi_over_phi_ss": 1.05},
        "sweep": {"k2_W": [0.3], "spread_D0": [0.0, 0.3]},
        "integrator": {"t_end": 1000.0},
        "catalogue": {"after": 0.2},
    },
)
ds = sweep.run(config, progress=False)
print(ds["slip_event_count"].values)  # events after the transient, per run
print(ds["system_wide_fraction"].values)  # fraction of them rupturing all 24 blocks

# %%
# ``sweep.plot_catalogue`` draws one run: each event a bar over the blocks it spanned
# from its start to its end, coloured by its magnitude (2/3) log10(slip/D0), beside
# the number of events of at least each magnitude and the Gutenberg–Richter line of
# the run's b-value. The disordered chain breaks into ruptures of many sizes.
fig = sweep.plot_catalogue(ds, {"k2_W": 0.3, "spread_D0": 0.3})
fig

r"""
How big a kick: the critical velocity jump
==========================================

Above the critical stiffness steady sliding is linearly stable, but a finite kick can
still leave it. Sweep the start like a parameter (``initial_v_over_V``, the velocity
jump v0/V from steady sliding) and bisect, at every stiffness, the smallest jump that
runs away past the velocity cap. With the slip law the threshold is **sharp**: the
excursion's peak :math:`\ln(v/V)` jumps from a few units to the cap across it (Gu, Rice,
Ruina & Tse 1984).
"""

import sweep

config = sweep.with_changes(
    "kick_slip_law", {"sweep": {"K_W": {"start": 0.0505, "stop": 0.085, "num": 8}}}
)
kicks = sweep.bisect_critical_kick(config, rtol=0.01, progress=False)
print(kicks["critical_kick"].values.round(3))
print(f"{int(kicks['kick_runs'].sum())} runs in {int(kicks.attrs['kick_rounds'])} rounds")

# %%
# The bars are the brackets (the largest jump that returned, the smallest that ran
# away); the filled markers say the threshold is sharp.
fig = sweep.plot_critical_kick(kicks)
fig

# %%
# The same question from a plain sweep over the kicks: ``sweep.critical_kick`` reduces
# any result swept over the start to its bracket at every other point (here the
# config's first scan, a factor √10 between kicks).
scan = sweep.critical_kick(sweep.run(config, progress=False))
print(scan["critical_kick_low"].values.round(2), scan["critical_kick"].values.round(2))

"""What makes a Dataset a complete sweep result, or a trace: the variables and
attributes a run writes, checked before a file is read on
(:func:`sweep.read_result`) and before a plot or a catalogue statistic uses a
Dataset it was given."""

import xarray as xr

from ..config import parse_config
from ..errors import ConfigError
from ..variables import REGIMES, variables_for

#: Variables by which a file is recognised as a sweep result at all.
RESULT_VARIABLES = ("regime", "K_over_Kc", "lnv_amplitude")
#: File attributes every sweep result has and the commands read.
RESULT_ATTRS = ("blocks", "model", "state_law", "initial_v_over_V", "initial_phi_over_phi_ss")
#: Attributes of a trace that its figure reads, beyond :data:`RESULT_ATTRS`, by regime.
TRACE_ATTRS = {"runaway": ("t_runaway", "classification_v_cap_over_V"), "stick_slip": ("period",)}


def check_result(ds, argument="ds"):
    """Raise TypeError unless ``ds`` is an xarray Dataset, ValueError (naming what is
    missing) unless it is a complete sweep result; ``argument`` names it in messages.
    The plotting and catalogue functions check what they are given with it."""
    if not isinstance(ds, xr.Dataset):
        raise TypeError(
            f"{argument} must be a result Dataset (xarray.open_dataset of a "
            f"result file), got {type(ds).__name__}"
        )
    missing = [v for v in RESULT_VARIABLES if v not in ds] or missing_parts(ds)
    if missing:
        raise ValueError(f"{argument} is not a complete sweep result: no {', '.join(missing)}")
    if ds["regime"].size == 0:
        raise ValueError(f"{argument} has no runs (an axis of length 0)")


def missing_parts(ds):
    """What a result ``ds`` lacks of what its run writes: the attributes the commands
    read, ``regime``'s flag table and, where its config is stored, the output variables
    of that config."""
    missing = [f"{a} attribute" for a in RESULT_ATTRS if a not in ds.attrs]
    missing += [
        f"regime {a}" for a in ("flag_values", "flag_meanings") if a not in ds["regime"].attrs
    ]
    try:
        config = parse_config(ds.attrs["config_text"])
    except (KeyError, ConfigError):  # none stored, or not valid: stored_config says so
        return missing
    expected = variables_for(config.blocks, config.model, config.features)
    return missing + [v.name for v in expected if v.name not in ds]


def check_trace(ds, argument="ds"):
    """Raise TypeError unless ``ds`` is an xarray Dataset, ValueError (naming what is
    missing) unless it is a trace (:func:`sweep.commands.trace.compute_trace`) with what its
    figure reads: the velocities, the run's regime and its statistics."""
    if not isinstance(ds, xr.Dataset):
        raise TypeError(f"{argument} must be a trace Dataset, got {type(ds).__name__}")
    if "velocity" not in ds:
        raise ValueError(
            f"{argument} must be a trace Dataset (sweep.commands.trace or python -m sweep trace)"
        )
    regime = ds.attrs.get("regime")
    if regime not in REGIMES:
        raise ValueError(
            f"{argument}: regime attribute must be one of {', '.join(REGIMES)}, got {regime!r}"
        )
    missing = [v for v in ("lnv", "time") if v not in ds.variables]
    missing += [
        f"{a} attribute"
        for a in (*RESULT_ATTRS, "K_over_Kc", *TRACE_ATTRS.get(regime, ()))
        if a not in ds.attrs
    ]
    missing += [] if "V" in ds.coords or "V" in ds.attrs else ["V coordinate"]
    if missing:
        raise ValueError(f"{argument} is not a complete trace: no {', '.join(missing)}")

"""The type of a boundary: the bifurcation the runs on its two sides name.

A boundary separates two labels (regime, attractor, events a cycle). Its type is read from
the runs next to it on each side, by these rules (Kuznetsov, *Elements of Applied
Bifurcation Theory*, 3rd ed. 2004: ch. 3 for the Hopf bifurcation of an equilibrium; ch. 4,
the fold, flip and Neimark-Sacker bifurcations of a map's fixed point, applied to a cycle's
Poincaré map in ch. 5: of its non-trivial multipliers μ, one reaching +1 is a fold of
cycles, −1 a period doubling, a complex pair reaching |μ| = 1 a torus):

- ``hopf``: steady sliding on one side, stick-slip on the other, and the linear growth
  rate at steady sliding negative on the steady side, positive (or zero, within
  :data:`GROWTH_ZERO`: a run on the critical line) on the other (an eigenpair crosses the
  imaginary axis between them); ``hopf (supercritical)`` etc. where the result
  has ``hopf_criticality`` and the runs agree on it;
- ``runaway``: one side runs away (velocity past the cap), whatever is on the other;
- ``period_doubling``: a cycle of n events beside one of 2n, or beside a quasi-periodic
  or chaotic run, with the n-event cycle's multiplier near −1;
- ``fold_of_cycles``: a cycle whose multiplier is near +1 beside steady sliding (with no
  sign change of the growth rate) or beside another cycle (events not doubled) or a
  quasi-periodic or chaotic run;
- ``torus``: a cycle with a complex pair near the unit circle beside a quasi-periodic run;
- ``undetermined``, with the reason: no rule for the two labels (e.g. a run on one side
  unresolved, or undecided), multipliers not computed, none near the unit circle, or
  evidence against the labels (events double but μ is not near −1).

A multiplier is *near* the unit circle where the largest non-trivial modulus of the runs
on that side next to the boundary is at least :data:`NEAR_UNIT`; it is real positive
(negative) where its argument lies within :data:`REAL_ANGLE` of 0 (π). A modulus of 1
within :data:`NEUTRAL_FACTOR` times the matrix's accuracy is a neutral cycle, one above
that an unstable one: neither names a bifurcation. These are coarse
on purpose: a multiplier crosses the unit circle only at the boundary, which a run can
approach no closer than its cell; a modulus of 0.5 at a corner of the cell says the cycle
is losing stability there, not that it lost it. The rules read only the runs' own outputs;
a boundary drawn between other labels (``sweep.boundaries(ds, outputs=...)``) is typed by
the same outputs of the runs on its sides.
"""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass

import numpy as np

#: The types a boundary can have (``hopf`` may carry its criticality in parentheses).
KINDS = ("hopf", "runaway", "period_doubling", "fold_of_cycles", "torus", "undetermined")
#: Smallest non-trivial multiplier modulus, next to the boundary, counted as approaching 1.
NEAR_UNIT = 0.5
#: Largest distance (rad) of a multiplier's argument from 0 or π for it to count as real.
REAL_ANGLE = 0.1
#: A multiplier whose modulus is 1 within this many times the trivial multiplier's distance
#: from 1 (``floquet_trivial_error``, the matrix's accuracy) is on the unit circle: a
#: neutral cycle (e.g. of the quasi-static aging law's family of closed orbits at Kc), no
#: evidence of a bifurcation beside it.
NEUTRAL_FACTOR = 10.0
#: Attractors other than periodic and fixed point a cycle can turn into (an unresolved run
#: says nothing of what lies beyond: no type beside it).
NON_PERIODIC = ("quasi_periodic", "chaotic")
#: A growth rate within this fraction of the largest on either side counts as zero: a run
#: on the critical line itself (e.g. at Kc, where the quasi-static aging law's family of
#: closed orbits lies).
GROWTH_ZERO = 1e-9


def run_table(ds):
    """The outputs the rules read, one value per run, as a dict of 1-D arrays (flag
    variables as their names); None for an ensemble result (runs with members)."""
    if "member" in ds["regime"].dims:
        return None
    table = {}
    for name in ("regime", "attractor", "floquet_status", "hopf_criticality"):
        if name in ds:
            meanings = np.array(ds[name].attrs["flag_meanings"].split())
            table[name] = meanings[ds[name].values.ravel().astype(int)]
    floquet = ("floquet_modulus", "floquet_argument", "floquet_trivial_error")
    for name in ("cycle_events", "linear_growth_rate", *floquet):
        if name in ds:
            table[name] = ds[name].values.ravel()
    return table


@dataclass(frozen=True)
class Side:
    """The runs on one side of a boundary, next to it: their regime, attractor and events
    a cycle (0 unless periodic), and the rows of ``table`` they are."""

    regime: str
    attractor: str
    events: int
    rows: np.ndarray

    @property
    def text(self):
        """The side in words, e.g. "periodic, 2 events"."""
        if self.attractor == "periodic":
            return f"periodic, {self.events} event" + ("s" if self.events != 1 else "")
        return self.regime if self.regime in ("steady", "runaway") else self.attractor


def classify(table, rows_a, rows_b):
    """The type of the boundary between the runs ``rows_a`` and ``rows_b`` of ``table``
    (:func:`run_table`), the runs next to it on its two sides: ``(kind, evidence)``."""
    if table is None:
        return "undetermined", "an ensemble result: its labels are regime fractions"
    sides = []
    for rows in (rows_a, rows_b):
        side = _side(table, np.asarray(rows))
        if isinstance(side, str):
            return "undetermined", side
        sides.append(side)
    a, b = sides
    if "unresolved" in (a.attractor, b.attractor):
        known = b if a.attractor == "unresolved" else a
        return "undetermined", f"unresolved runs beside {known.text}: what lies beyond is unknown"
    if "runaway" in (a.regime, b.regime):
        other = b if a.regime == "runaway" else a
        if other.regime == "runaway":
            return "undetermined", "runaway on both sides"
        return "runaway", f"runaway beside {other.text}"
    if {a.regime, b.regime} == {"steady", "stick_slip"}:
        steady, moving = (a, b) if a.regime == "steady" else (b, a)
        return _steady_edge(table, steady, moving)
    if a.attractor == b.attractor == "periodic":
        return _between_cycles(table, *sorted((a, b), key=lambda s: s.events))
    if "periodic" in (a.attractor, b.attractor):
        cycle, other = (a, b) if a.attractor == "periodic" else (b, a)
        if other.attractor in NON_PERIODIC:
            return _cycle_lost(table, cycle, other)
    return "undetermined", f"no rule for {a.text} beside {b.text}"


def _side(table, rows):
    """A :class:`Side` of ``rows``, or the reason they are not one (they differ)."""
    regimes = sorted(set(table["regime"][rows]))
    attractors = sorted(set(table["attractor"][rows]))
    periodic = table["attractor"][rows] == "periodic"
    events = table["cycle_events"][rows] if "cycle_events" in table else np.zeros(len(rows))
    counts = sorted({int(n) for n in np.where(periodic, events, 0)})
    if len(regimes) > 1 or len(attractors) > 1 or len(counts) > 1:
        return (
            "the runs on one side differ: "
            f"{', '.join(regimes + attractors)}, events {', '.join(map(str, counts))}"
        )
    return Side(str(regimes[0]), str(attractors[0]), counts[0], rows)


def _steady_edge(table, steady, moving):
    """Steady sliding beside stick-slip: Hopf where the growth rate changes sign, fold of
    cycles where it does not and the cycle's multiplier is near +1."""
    if "linear_growth_rate" not in table:
        return "undetermined", "no linear_growth_rate in this result"
    low = table["linear_growth_rate"][steady.rows]
    high = table["linear_growth_rate"][moving.rows]
    if np.isnan(low).any() or np.isnan(high).any():
        return "undetermined", "linear_growth_rate not given beside the boundary"
    zero = GROWTH_ZERO * max(np.abs(low).max(), np.abs(high).max())
    low, high = np.where(np.abs(low) <= zero, 0.0, low), np.where(np.abs(high) <= zero, 0.0, high)
    rates = f"growth rate {low.max():.3g} s⁻¹ (steady), {high.min():.3g} s⁻¹ (stick-slip)"
    if low.max() < 0 <= high.min():
        return _hopf(table, steady, moving), f"{rates}: an eigenpair crosses"
    if high.max() < 0 and moving.attractor == "periodic":
        near, text = _multiplier(table, moving)
        if near == "plus":
            return "fold_of_cycles", f"{rates}, no sign change; {text}"
        return "undetermined", f"{rates}, no sign change; {text}, not near +1"
    return "undetermined", f"steady beside {moving.text}, {rates}"


def _hopf(table, steady, moving):
    """``hopf``, with the criticality the runs beside it agree on if the result has it."""
    if "hopf_criticality" not in table:
        return "hopf"
    rows = np.concatenate([steady.rows, moving.rows])
    found = set(table["hopf_criticality"][rows])
    if len(found) == 1 and found <= {"supercritical", "subcritical", "degenerate"}:
        return f"hopf ({found.pop()})"
    return "hopf"


def _between_cycles(table, low, high):
    """A cycle of ``low.events`` beside one of ``high.events``: period doubling where they
    double and the shorter cycle's multiplier is near −1; fold of cycles where either
    multiplier is near +1 and they do not double."""
    nears = [_multiplier(table, side) for side in (low, high)]
    if high.events == 2 * low.events:
        near, text = nears[0]
        if near == "minus":
            return "period_doubling", f"{low.events} → {high.events} events; {text}"
        return "undetermined", f"{low.events} → {high.events} events but {text}, not near −1"
    found = [(n, t) for n, t in nears if n == "plus"]
    if found:
        return "fold_of_cycles", f"{low.events} ↔ {high.events} events; {found[0][1]}"
    texts = "; ".join(t for _, t in nears)
    return "undetermined", f"{low.events} ↔ {high.events} events, not doubled; {texts}"


def _cycle_lost(table, cycle, other):
    """A cycle beside a non-periodic attractor: period doubling (μ near −1), torus (a
    complex pair near the unit circle, quasi-periodic beyond) or fold of cycles (+1)."""
    near, text = _multiplier(table, cycle)
    where = f"{cycle.text} beside {other.attractor}; {text}"
    if near == "minus":
        return "period_doubling", where
    if near == "plus":
        return "fold_of_cycles", where
    if near == "complex" and other.attractor == "quasi_periodic":
        return "torus", where
    return "undetermined", where


def _multiplier(table, side):
    """How a cycle's largest non-trivial multiplier stands next to the boundary: ``(near,
    text)``, ``near`` "minus", "plus", "complex" (near the unit circle), "inside" (not
    near), "neutral" (on it within the matrix's accuracy), "unstable" (outside it) or
    "missing" (not computed)."""
    if "floquet_modulus" not in table:
        return "missing", "no Floquet multipliers in this result"
    status = table["floquet_status"][side.rows]
    rows = side.rows[np.isin(status, ("ok", "at_resolution"))]
    if len(rows) == 0:
        why = ", ".join(sorted(set(status)))
        return "missing", f"multipliers of the {side.text} cycle not computed ({why})"
    modulus = table["floquet_modulus"][rows]
    at = int(np.argmax(modulus))
    mod, arg = float(modulus[at]), float(table["floquet_argument"][rows][at])
    text = f"|μ| = {mod:.3g}, arg μ = {arg:.3g} rad on the {side.text} side"
    accuracy = NEUTRAL_FACTOR * float(table["floquet_trivial_error"][rows][at])
    if abs(mod - 1) <= accuracy:
        return "neutral", f"{text}: 1 within its accuracy, a neutral cycle (a family of orbits?)"
    if mod > 1:
        return "unstable", f"{text}: above 1, an unstable cycle though labelled periodic"
    if mod < NEAR_UNIT:
        return "inside", text
    if abs(arg) <= REAL_ANGLE:
        return "plus", text
    if abs(arg) >= np.pi - REAL_ANGLE:
        return "minus", text
    return "complex", text


def combine(verdicts):
    """One ``(kind, evidence)`` of a polyline from its cells' ``(kind, evidence)``: the
    kind every determined cell gives; undetermined where none is or they disagree."""
    kinds = Counter(kind for kind, _ in verdicts)
    determined = [k for k in kinds if k != "undetermined"]
    n = len(verdicts)
    if len(determined) > 1:
        found = ", ".join(f"{k} in {c}" for k, c in kinds.most_common())
        return "undetermined", f"the cells disagree: {found} of {n}"
    if not determined:
        reasons = Counter(evidence for _, evidence in verdicts)
        return "undetermined", reasons.most_common(1)[0][0] + (f" ({n} cells)" if n > 1 else "")
    kind = determined[0]
    evidence = next(e for k, e in verdicts if k == kind)
    if n > 1:
        evidence += f" (its first cell; {kind} in {kinds[kind]} of {n} cells)"
    return kind, evidence


@dataclass(frozen=True)
class Crossing:
    """A change of label between neighbouring points of a 1-D result: between points
    ``index`` and ``index + 1``, at ``position`` (the middle, in the axis' units), the
    labels ``between`` and the boundary's ``kind`` and ``evidence``."""

    index: int
    position: float
    between: tuple
    kind: str
    evidence: str


def boundary_types_1d(ds, axis=None):
    """The boundaries between neighbouring points of a 1-D result and their types.

    Parameters
    ----------
    ds : xarray.Dataset
        A grid result (not refined: see :func:`sweep.boundaries`) without members.
    axis : str, optional
        The sweep axis (default: the first with more than one value); the other axes
        are taken at their first value.

    Returns
    -------
    list of Crossing
        One per pair of neighbours whose labels (regime, attractor, events a cycle)
        differ, in the order of the axis' values.

    Raises
    ------
    ValueError
        ``axis`` is not a sweep axis, or the result is an ensemble.
    """
    dims = list(ds["regime"].dims)
    if "member" in dims:
        raise ValueError("boundary_types_1d: an ensemble result (runs with members)")
    axis = axis or next((d for d in dims if ds.sizes[d] > 1), dims[0] if dims else None)
    if axis not in dims:
        raise ValueError(f"boundary_types_1d: no sweep axis {axis!r}; the axes are {dims}")
    line = ds.isel({d: 0 for d in dims if d != axis}).sortby(axis)
    table = run_table(line)
    x = line[axis].values
    sides = [_side(table, np.array([i])) for i in range(len(x))]
    out = []
    for i in range(len(x) - 1):
        a, b = sides[i], sides[i + 1]
        if (a.regime, a.attractor, a.events) == (b.regime, b.attractor, b.events):
            continue
        kind, evidence = classify(table, [i], [i + 1])
        middle = float((x[i] + x[i + 1]) / 2)
        out.append(Crossing(i, middle, (_label(a), _label(b)), kind, evidence))
    return out


def _label(side):
    """The label of a side as :func:`sweep.boundaries` writes it."""
    return side.text if side.regime in ("steady", "runaway") else f"{side.regime}, {side.text}"

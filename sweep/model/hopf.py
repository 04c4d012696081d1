"""Hopf criticality of steady sliding: the first Lyapunov coefficient l1 at κ = κc.

Plain numpy. Where steady sliding loses stability (the common κ = κc of
``linear``, the engine's ``critical_K_W``) a pair of eigenvalues ±iω of the Jacobian A
crosses the imaginary axis. The first Lyapunov coefficient (Kuznetsov 2004, *Elements
of Applied Bifurcation Theory*, 3rd ed., §3.5 and §5.4; the same formula in the MatCont
manual, eq. 40, and the notes arXiv:2511.08428, eq. 1)::

    l1 = 1/(2ω) Re[ ⟨p, C(q, q, q̄)⟩ − 2 ⟨p, B(q, A⁻¹ B(q, q̄))⟩
                   + ⟨p, B(q̄, (2iω I − A)⁻¹ B(q, q))⟩ ]

with A q = iω q, Aᵀ p = −iω p, ⟨p, q⟩ = p̄ᵀ q = 1 and ⟨q, q⟩ = 1, and B, C the second
and third derivatives of the right-hand side at steady sliding (symmetric multilinear
forms), decides the bifurcation: l1 < 0 supercritical (a stable cycle grows as the
square root of the distance past κc), l1 > 0 subcritical (an unstable cycle around
the stable steady state above κc), l1 = 0 degenerate (the quasi-static aging law:
Ranjith & Rice 1999). Its sign does not depend on the coordinates, its size does: here
the state is the engine's (ℓ_1…ℓ_N, ψ_1…ψ_N[, z_1…z_N]) and time is in units of the
reference D0/V (``sweep/kernels/equations.py``; :func:`rhs`).

B and C are exact to round-off: :func:`rhs` is evaluated on truncated Taylor series in
three nilpotent directions (``Jet``: ε_k² = 0, the hyper-dual numbers of Fike & Alonso
2011), whose coefficient of ε1ε2 is B(u, v) and of ε1ε2ε3 is C(u, v, w); no step size,
no difference quotient.

Near κc, where l1 < 0, the normal form ż = λ(κ) z + c1 z|z|², Re c1 = ω l1 (Kuznetsov
§3.5), has the cycle |z|² = −Re λ / Re c1, and the state is x ≈ 2 Re(z q e^{iωt}):
block i's ln(v_i/V) swings over 4 |z| |q_ℓi| peak to peak. The engine's
``lnv_amplitude`` is the maximum over all blocks minus the minimum over all blocks,
to leading order 4 |z| max_i |q_ℓi|, which is :func:`predicted_lnv_amplitude`.
"""

import functools
from dataclasses import dataclass

import numpy as np

from ..codes import HOPF_CRITICALITIES, code
from . import heterogeneity, linear, physics

#: l1 is called degenerate where |l1| ≤ DEGENERATE_TOLERANCE × the sum of the moduli
#: of the formula's three terms (each / 2ω). Where l1 = 0 in exact arithmetic (the
#: quasi-static model, either law) round-off (of the eigenvectors and of κc) leaves
#: below 1e-14 of that sum, for one block and for chains of up to 64 identical blocks;
#: an unfolding by unequal blocks grows as the square of their spread, 1e-9 of the sum
#: at a relative D0 spread of 1e-4 in an 8-block chain: below the tolerance it is not
#: told from round-off.
DEGENERATE_TOLERANCE = 1e-9
#: The critical pair is not simple where another eigenvalue's real part is within
#: SIMPLE_TOLERANCE × ω of the pair's (identical uncoupled blocks: every block's pair
#: on the axis at once), or is no pair where ω ≤ SIMPLE_TOLERANCE × max |λ|.
SIMPLE_TOLERANCE = 1e-8

#: Jet coefficients: index = bit mask of the nilpotent directions ε1, ε2, ε3 it
#: multiplies; a product's coefficient of mask S sums a[T] b[S − T] over T ⊆ S.
N_DIRECTIONS = 3
N_COEFFICIENTS = 1 << N_DIRECTIONS
PRODUCT_TERMS = tuple(
    (s, t, s ^ t) for s in range(N_COEFFICIENTS) for t in range(N_COEFFICIENTS) if t & s == t
)


class Jet:
    """A vector function of ε1, ε2, ε3 with ε_k² = 0: coefficients ``c`` (8, n),
    ``c[mask]`` multiplying the product of the ε's in ``mask``."""

    __array_ufunc__ = None  # numpy arrays defer to the reflected operators below

    def __init__(self, c):
        self.c = c

    @classmethod
    def seed(cls, x0, directions):
        """x0 + Σ_k ε_k directions[k] (complex, up to three directions)."""
        c = np.zeros((N_COEFFICIENTS, x0.size), complex)
        c[0] = x0
        for k, u in enumerate(directions):
            c[1 << k] = u
        return cls(c)

    def __getitem__(self, index):
        return Jet(self.c[:, index])

    def __add__(self, other):
        if isinstance(other, Jet):
            return Jet(self.c + other.c)
        c = self.c.copy()
        c[0] = c[0] + other
        return Jet(c)

    __radd__ = __add__

    def __neg__(self):
        return Jet(-self.c)

    def __sub__(self, other):
        return self + (-other)

    def __rsub__(self, other):
        return (-self) + other

    def __mul__(self, other):
        if not isinstance(other, Jet):
            return Jet(self.c * other)
        out = np.zeros(np.broadcast_shapes(self.c.shape, other.c.shape), complex)
        for s, t, rest in PRODUCT_TERMS:
            out[s] += self.c[t] * other.c[rest]
        return Jet(out)

    __rmul__ = __mul__

    def __truediv__(self, other):
        if isinstance(other, Jet):
            return self * other.reciprocal()
        return Jet(self.c / other)

    def _series(self, f0, coefficients):
        """f0 Σ_k coefficients[k] n^k with n = self minus its value part: a function's
        Taylor series about the value part, exact at the third power (n⁴ = 0)."""
        n = Jet(self.c.copy())
        n.c[0] = 0.0
        term = Jet(np.zeros_like(self.c))
        term.c[0] = 1.0
        out = Jet(np.zeros_like(self.c))
        for a in coefficients:
            out = out + term * a
            term = term * n
        return out * f0

    def exp(self):
        """e^self."""
        return self._series(np.exp(self.c[0]), (1.0, 1.0, 1.0 / 2.0, 1.0 / 6.0))

    def reciprocal(self):
        """1/self."""
        inv = 1.0 / self.c[0]
        return self._series(inv, (1.0, -inv, inv**2, -(inv**3)))

    def coupled(self, lap):
        """Σ_j L_ij self_j for the Laplacian ``lap`` (n × n)."""
        return Jet(self.c @ lap.T)


def concatenate(jets):
    """The jets one after the other along the vector axis."""
    return Jet(np.concatenate([j.c for j in jets], axis=1))


@dataclass(frozen=True, eq=False)
class Blocks:
    """One system at common stiffness κ: per-block arrays ``A``, ``B``, ``kappa1``
    (κ1_i = K_i D0/W), ``rate`` (D0/D0_i); coupling κ2 = k2 D0/W on the springs of the
    Laplacian ``lap``; η̂ = ηV/W, M̂ = mV²/(W D0); ``model`` and ``law`` by name."""

    model: str
    law: str
    A: np.ndarray
    B: np.ndarray
    kappa1: np.ndarray
    rate: np.ndarray
    kappa2: float
    lap: np.ndarray
    eta_hat: float = 0.0
    mass_hat: float = 0.0

    def __post_init__(self):
        if self.model not in physics.MODELS:
            raise ValueError(f"model must be one of {physics.MODELS}, got {self.model!r}")
        if self.law not in physics.STATE_LAWS:
            raise ValueError(f"state law must be one of {physics.STATE_LAWS}, got {self.law!r}")

    @property
    def size(self):
        """State variables: 2 per block, 3 with inertia."""
        return (3 if self.model == "inertial" else 2) * self.A.size

    def jacobian(self):
        """The Jacobian at steady sliding (``linear.steady_jacobian``), V/D0."""
        return linear.steady_jacobian(
            self.model,
            self.A,
            self.B,
            self.kappa1,
            self.rate,
            self.kappa2,
            self.lap,
            self.eta_hat,
            self.mass_hat,
        )


def rhs(blocks, y):
    """dy/dτ of the log form (``sweep/kernels/equations.py``) at the jet ``y``, per D0/V.

    ψ_i' = r_i (e^(−ψ_i) − e^ℓ_i) (aging) or −r_i e^ℓ_i (ℓ_i + ψ_i) (slip), r_i = D0/D0_i;
    the drive d_i = κ1_i (1 − e^ℓ_i) − κ2 Σ_j L_ij e^ℓ_j − B_i ψ_i'; ℓ_i' = d_i/A_i
    (quasi-static), d_i/(A_i + η̂ e^ℓ_i) (quasi-dynamic), or z_i e^(−ℓ_i)/M̂ with
    z_i' = d_i − A_i ℓ_i' (inertial).
    """
    nb = blocks.A.size
    lnv, psi = y[:nb], y[nb : 2 * nb]
    v = lnv.exp()
    if blocks.law == "aging":
        dpsi = (-psi).exp() - v
    else:
        dpsi = -(v * (lnv + psi))
    dpsi = dpsi * blocks.rate
    drive = blocks.kappa1 * (1.0 - v) - blocks.kappa2 * v.coupled(blocks.lap) - blocks.B * dpsi
    if blocks.model == "quasi-static":
        return concatenate([drive / blocks.A, dpsi])
    if blocks.model == "quasi-dynamic":
        return concatenate([drive / (blocks.A + blocks.eta_hat * v), dpsi])
    dlnv = y[2 * nb :] * (-lnv).exp() / blocks.mass_hat
    return concatenate([dlnv, dpsi, drive - blocks.A * dlnv])


def derivative(blocks, *directions):
    """The derivative of :func:`rhs` at steady sliding along ``directions`` (one to
    three complex vectors): J u, B(u, v) or C(u, v, w)."""
    y = Jet.seed(np.zeros(blocks.size), directions)
    return rhs(blocks, y).c[(1 << len(directions)) - 1]


@dataclass(frozen=True)
class Criticality:
    """The Hopf point of one system: ``l1`` (NaN unless the pair is simple), the status
    code (:data:`~sweep.codes.HOPF_CRITICALITIES`), ``omega`` (V/D0) and ``lnv_weight``
    = max_i |q_ℓi| of the normalised critical eigenvector."""

    l1: float
    status: int
    omega: float = np.nan
    lnv_weight: float = np.nan


def without_l1(status):
    """A :class:`Criticality` without l1, with the named status."""
    return Criticality(np.nan, code(HOPF_CRITICALITIES, status))


def criticality(blocks):
    """l1 (Kuznetsov's formula) of ``blocks`` at its κ, which must be κc.

    The critical pair is the eigenvalue with Im λ > 0 and the largest real part; no
    pair if a real eigenvalue lies further right (``no_hopf``), not simple if another
    eigenvalue is as far right within :data:`SIMPLE_TOLERANCE` ω (``not_simple``).
    q is the right eigenvector of the pair, p the left one of Aᵀ at −iω (a second
    eigendecomposition, matched by eigenvalue), scaled to ⟨q, q⟩ = ⟨p, q⟩ = 1.
    """
    jac = blocks.jacobian()
    lam, vec = np.linalg.eig(jac)
    pair = np.where(lam.imag > 0.0, lam.real, -np.inf)
    c = int(np.argmax(pair))
    omega = lam[c].imag
    if not omega > SIMPLE_TOLERANCE * np.abs(lam).max() or lam[c].real < lam.real.max() - (
        SIMPLE_TOLERANCE * omega
    ):
        return without_l1("no_hopf")
    others = np.ones(lam.size, bool)
    others[[c, int(np.argmin(np.abs(lam - lam[c].conj())))]] = False
    if others.any() and lam[others].real.max() >= lam[c].real - SIMPLE_TOLERANCE * omega:
        return without_l1("not_simple")
    q = vec[:, c] / np.linalg.norm(vec[:, c])
    lam_t, vec_t = np.linalg.eig(jac.T)
    p = vec_t[:, int(np.argmin(np.abs(lam_t - lam[c].conj())))]
    p = p / np.vdot(p, q).conj()  # ⟨p, q⟩ = p̄ᵀ q = 1
    eye = np.eye(jac.shape[0])
    h11 = np.linalg.solve(jac, derivative(blocks, q, q.conj()))
    h20 = np.linalg.solve(2j * omega * eye - jac, derivative(blocks, q, q))
    terms = np.array(
        [
            np.vdot(p, derivative(blocks, q, q, q.conj())),
            -2.0 * np.vdot(p, derivative(blocks, q, h11)),
            np.vdot(p, derivative(blocks, q.conj(), h20)),
        ]
    ) / (2.0 * omega)
    l1 = terms.sum().real
    if abs(l1) <= DEGENERATE_TOLERANCE * np.abs(terms).sum():
        status = "degenerate"
    else:
        status = "supercritical" if l1 < 0.0 else "subcritical"
    weight = np.abs(q[: blocks.A.size]).max()
    return Criticality(l1, code(HOPF_CRITICALITIES, status), omega, weight)


@functools.lru_cache(maxsize=4096)
def one_block(model, law, A, B, eta_hat, mass_hat):
    """:class:`Criticality` of one block at its analytic κc (``physics.critical_kappa``)."""
    kc = float(physics.critical_kappa(model, A, B, eta_hat, mass_hat))
    if not kc > 0.0:
        return without_l1("no_hopf")
    one = np.ones(1)
    lap = np.zeros((1, 1))
    return criticality(
        Blocks(model, law, A * one, B * one, kc * one, one, 0.0, lap, eta_hat, mass_hat)
    )


@functools.lru_cache(maxsize=4096)
def unequal_blocks(model, law, coupling, nb, key):
    """:class:`Criticality` of unequal blocks at their common κc (``linear._critical``,
    whose ``key`` it takes: (A_i…, B_i…, K_i/K…, D0/D0_i…, κ2, η̂, M̂))."""
    kc, _ = linear._critical(model, coupling, nb, key)
    if not kc > 0.0:
        return without_l1("no_hopf")
    k = np.array(key)
    A, B, ratio, rate = (k[i * nb : (i + 1) * nb] for i in range(4))
    kappa2, eta_hat, mass_hat = k[4 * nb :]
    lap = linear.laplacian(nb, coupling)
    return criticality(Blocks(model, law, A, B, ratio * kc, rate, kappa2, lap, eta_hat, mass_hat))


def identical_blocks(model, law, nb, A, B, kappa2, eta_hat, mass_hat):
    """:class:`Criticality` of ``nb`` identical blocks: the in-phase mode is one block
    (``physics.critical_kappa``), its eigenvectors the one block's / √nb (⟨q, q⟩ = 1),
    so l1 is the one block's / nb; without coupling springs (κ2 = 0) every block's pair
    crosses at once: not simple."""
    one = one_block(model, law, A, B, eta_hat, mass_hat)
    if nb > 1 and kappa2 == 0.0 and one.status != code(HOPF_CRITICALITIES, "no_hopf"):
        return without_l1("not_simple")
    return Criticality(one.l1 / nb, one.status, one.omega, one.lnv_weight / np.sqrt(nb))


#: The normal form's amplitude is given where the growth rate past κc is at most this
#: fraction of the onset frequency (its small parameter): K/Kc ≳ 0.8 for one block with
#: η̂ = 0.01; far past κc (an inertial chain at K/Kc 0.02 gave 4.98) it means nothing.
NORMAL_FORM_RANGE = 0.1


def predicted_lnv_amplitude(l1, omega, lnv_weight, growth):
    """Peak-to-peak ln(v/V) of the normal form's cycle, 4 |z| max_i |q_ℓi| with
    |z|² = −Re λ/(ω l1), Re c1 = ω l1: ``growth`` = Re λ at the system's κ (V/D0),
    ``lnv_weight`` = max_i |q_ℓi|. Meaningful for l1 < 0 and Re λ > 0 only."""
    return 4.0 * lnv_weight * np.sqrt(-growth / (omega * l1))


def theory(config, phys, dl, values, growth):
    """Hopf criticality at every system of a sweep, from the arguments of
    ``linear.theory`` and its ``growth_rate`` (``growth``, V/D0).

    Returns a dict of arrays: ``l1`` (dimensionless: the engine's state variables, time
    in D0/V, ⟨q, q⟩ = ⟨p, q⟩ = 1), ``criticality`` (codes of
    :data:`~sweep.codes.HOPF_CRITICALITIES`) and ``lnv_amplitude``
    (:func:`predicted_lnv_amplitude` where supercritical, past κc and near it: 0 < Re λ ≤
    ``NORMAL_FORM_RANGE`` ω, else NaN). Each
    distinct parameter set is computed once (cached).
    """
    n = growth.shape[0]
    nb = config.blocks
    unequal = np.zeros(n, bool)
    if config.heterogeneous:
        unequal = ~heterogeneity.identical_blocks(values)
        factors = heterogeneity.block_factors(config, phys)
        keys = np.column_stack(
            [
                values["A"],
                values["B"],
                factors["K_W"],
                1.0 / factors["D0"],
                dl["kappa2"],
                dl["eta_hat"],
                dl["mass_hat"],
            ]
        )
    common = np.column_stack(
        [np.broadcast_to(dl[name], (n,)) for name in ("A", "B", "kappa2", "eta_hat", "mass_hat")]
    )
    found = [
        unequal_blocks(config.model, config.state_law, config.coupling, nb, tuple(keys[r].tolist()))
        if unequal[r]
        else identical_blocks(config.model, config.state_law, nb, *common[r].tolist())
        for r in range(n)
    ]
    l1, omega, weight = (
        np.array([getattr(f, k) for f in found]) for k in ("l1", "omega", "lnv_weight")
    )
    status = np.array([f.status for f in found], np.int8)
    near = (growth > 0.0) & (growth <= NORMAL_FORM_RANGE * omega)
    past = (status == code(HOPF_CRITICALITIES, "supercritical")) & near
    with np.errstate(invalid="ignore", divide="ignore"):  # NaN where not past
        amplitude = np.where(past, predicted_lnv_amplitude(l1, omega, weight, growth), np.nan)
    return {"l1": l1, "criticality": status, "lnv_amplitude": amplitude}

"""Impact studies: breakage probability and the Vogel & Peukert master curve.

Vogel & Peukert (2003) write the probability that a particle of size x breaks after k
impacts at mass-specific kinetic energy W_m,kin (J/kg) as

    P = 1 - exp(-f_mat x k (W_m,kin - W_m,min))      for W_m,kin > W_m,min, else 0,

with f_mat (kg/(J m)) a material property and W_m,min (J/kg) the energy below which
nothing breaks. L. Vogel, W. Peukert, "Breakage behaviour of different materials -
construction of a mastercurve for the breakage probability", Powder Technology 129 (2003)
101-110.

``fit_master_curve`` fits (f_mat x k, W_m,min) to per-case outcomes (0/1 or fractions)
by least squares (scipy.optimize.curve_fit): the model is the expected outcome given the
energy, so raw 0/1 outcomes need no binning and random velocity designs fit as well as
grids. ``cluster_impact`` is a small self-contained impact case for studies and tests:
a cubic bonded cluster whose bottom layer is stopped dead (a sticking rigid target) while
the rest still moves at the impact velocity.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np


def master_curve(specific_energy, rate, minimum_energy):
    """Vogel-Peukert breakage probability.

    specific_energy: W_m,kin, J/kg (array); rate: f_mat x k, kg/J; minimum_energy:
    W_m,min, J/kg. Returns P in [0, 1).
    """
    excess = np.maximum(np.asarray(specific_energy, dtype=np.float64) - minimum_energy, 0.0)
    return -np.expm1(-rate * excess)


@dataclass(frozen=True)
class MasterCurveFit:
    """Fitted Vogel-Peukert parameters.

    rate: f_mat x k, kg/J, with standard error rate_error; minimum_energy: W_m,min, J/kg,
    with minimum_energy_error; f_mat: kg/(J m) when the particle size was given (else NaN);
    cases: number of outcomes fitted.
    """
    rate: float
    rate_error: float
    minimum_energy: float
    minimum_energy_error: float
    f_mat: float
    cases: int

    def probability(self, specific_energy):
        """Fitted breakage probability at specific_energy (J/kg)."""
        return master_curve(specific_energy, self.rate, self.minimum_energy)


def fit_master_curve(specific_energy, outcome, *, size=None, impacts=1):
    """Fit P = 1 - exp(-f_mat x k (W - W_min)) to outcomes by least squares.

    specific_energy: (n,) J/kg; outcome: (n,) 1 broken / 0 intact, or observed
    probabilities; size: particle size x, m (optional, gives f_mat); impacts: k.
    Returns a MasterCurveFit. Raises ValueError when the data cannot determine the curve
    (fewer than 3 points, or no breakage / only breakage).
    """
    from scipy.optimize import curve_fit

    energy = np.asarray(specific_energy, dtype=np.float64).ravel()
    outcome = np.asarray(outcome, dtype=np.float64).ravel()
    if energy.shape != outcome.shape or energy.size < 3:
        raise ValueError(f"fit_master_curve: need >= 3 paired points, got {energy.size} "
                         f"energies and {outcome.size} outcomes")
    if not (np.all(np.isfinite(energy)) and np.all(np.isfinite(outcome))):
        raise ValueError("fit_master_curve: energies and outcomes must be finite")
    if not (outcome.max() > 0.0 and outcome.min() < 1.0):
        raise ValueError("fit_master_curve: outcomes are all 0 or all 1; the master curve "
                         "needs energies both below and above breakage")
    # Starting point: W_min just below the lowest energy that broke; the rate from the
    # mean outcome above it, inverting P = 1 - exp(-rate dW) at the median excess.
    broke = energy[outcome > 0.0]
    w_min0 = broke.min() * 0.99 if broke.min() > 0 else broke.min() - 1e-12
    above = energy > w_min0
    p_mean = min(max(outcome[above].mean(), 0.05), 0.95)
    excess = max(float(np.median(energy[above] - w_min0)), 1e-300)
    rate0 = -math.log1p(-p_mean) / excess
    params, covariance = curve_fit(master_curve, energy, outcome, p0=(rate0, w_min0),
                                   bounds=([0.0, -np.inf], [np.inf, np.inf]), maxfev=20000)
    errors = np.sqrt(np.diag(covariance)) if np.all(np.isfinite(covariance)) else (np.nan,) * 2
    rate, w_min = (float(p) for p in params)
    f_mat = rate / (size * impacts) if size else math.nan
    return MasterCurveFit(rate, float(errors[0]), w_min, float(errors[1]), f_mat, energy.size)


def breakage_probability(x, outcome, *, bins=None):
    """Observed breakage probability per distinct x (or per bin when ``bins`` is given).

    x: (n,) impact velocity (m/s) or specific energy (J/kg); outcome: (n,) 0/1.
    bins: None (group equal x values) or an int / edges for numpy.histogram_bin_edges.
    Returns (centres, probability, count, standard_error) arrays; the standard error is the
    binomial sqrt(p (1 - p) / n).
    """
    x = np.asarray(x, dtype=np.float64).ravel()
    outcome = np.asarray(outcome, dtype=np.float64).ravel()
    if bins is None:
        centres, group = np.unique(x, return_inverse=True)
    else:
        edges = np.histogram_bin_edges(x, bins=bins)
        group = np.clip(np.searchsorted(edges, x, side="right") - 1, 0, edges.size - 2)
        used = np.unique(group)
        centres = (0.5 * (edges[:-1] + edges[1:]))[used]
        group = np.searchsorted(used, group)
    count = np.bincount(group, minlength=centres.size)
    probability = np.bincount(group, weights=outcome, minlength=centres.size) / count
    error = np.sqrt(probability * (1.0 - probability) / count)
    return centres, probability, count, error


def plot_master_curve(specific_energy, outcome, fit, path, *, bins=None, title=None):
    """Plot observed breakage probability (points with binomial error bars) and the fitted
    master curve against specific energy (J/kg); write PNG or PDF (by suffix) to path."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    centres, probability, count, error = breakage_probability(specific_energy, outcome,
                                                              bins=bins)
    figure, axes = plt.subplots(figsize=(6, 4.2))
    axes.errorbar(centres, probability, yerr=error, fmt="o", ms=4, capsize=2,
                  label=f"simulated ({int(count.sum())} cases)")
    grid = np.linspace(0.0, max(float(np.max(specific_energy)), fit.minimum_energy) * 1.05, 300)
    axes.plot(grid, fit.probability(grid), "-",
              label=(f"Vogel-Peukert: f_mat x k = {fit.rate:.3g} kg/J, "
                     f"W_m,min = {fit.minimum_energy:.3g} J/kg"))
    axes.set_xlabel("mass-specific impact energy W_m,kin (J/kg)")
    axes.set_ylabel("breakage probability P")
    axes.set_ylim(-0.03, 1.03)
    axes.legend(loc="lower right", fontsize=8)
    if title:
        axes.set_title(title)
    figure.tight_layout()
    figure.savefig(path)
    plt.close(figure)
    return path


# --- a self-contained impact case ---------------------------------------------------------

def cluster_impact(params, case_dir, seed):
    """One impact of a bonded cubic cluster on a sticking rigid target (study runner).

    params: ``impact_velocity`` (m/s, required); optional ``normal_strength`` (Weibull
    scale of the bond strengths, Pa, default 1e6), ``weibull_modulus`` (default 5),
    ``size`` (particles per cube edge, default 3), ``duration`` (s, default 1e-3).
    Particles: radius 1 mm, spacing 2 mm, glass (2500 kg/m^3, E 1e8 Pa); bonds between
    nearest neighbours, diameter 1 mm, E 1e8 Pa, tangential strength = normal strength,
    each bond's strength drawn from the Weibull law with ``seed`` (flaws make breakage
    statistical). At t = 0 the bottom layer is stopped dead (fixed), the rest moves at
    -impact_velocity along z: the compression wave loads the bottom bonds, which may break
    (compressive breakage on), then the rebound stretches them.

    Returns broken_bond_fraction, largest_fragment_fraction (mass fraction of the largest
    set of particles joined by intact bonds), peak_wall_force (N, largest |force| the
    target exerts, i.e. on the stopped layer) and specific_energy (J/kg, v^2/2).
    case_dir is not used (nothing is written).
    """
    import bondem

    speed = float(params["impact_velocity"])
    strength = float(params.get("normal_strength", 1e6))
    modulus = float(params.get("weibull_modulus", 5.0))
    size = int(params.get("size", 3))
    duration = float(params.get("duration", 1e-3))
    spacing, radius = 2e-3, 1e-3
    index = np.arange(size)
    grid = np.stack(np.meshgrid(index, index, index, indexing="ij"), axis=-1).reshape(-1, 3)
    position = grid * spacing
    flat = lambda g: (g[:, 0] * size + g[:, 1]) * size + g[:, 2]  # noqa: E731
    bonds = []
    for axis in range(3):
        lower = grid[grid[:, axis] < size - 1]
        upper = lower + np.eye(3, dtype=int)[axis]
        bonds.append(np.stack([flat(lower), flat(upper)], axis=1))
    bonds = np.concatenate(bonds)
    rng = np.random.default_rng(seed)
    strengths = strength * rng.weibull(modulus, size=bonds.shape[0])
    bond_materials = [bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3,
                                          normal_strength=s, tangential_strength=s,
                                          compressive_breakage=True, name=f"b{k}")
                      for k, s in enumerate(strengths)]
    glass = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, name="glass")
    bottom = grid[:, 2] == 0
    velocity = np.zeros((grid.shape[0], 3))
    velocity[~bottom, 2] = -speed
    model, state = bondem.make_system(position, radius, glass, velocity=velocity,
                                      fixed=bottom, bonds=bonds, bond_diameter=1e-3,
                                      bond_material=bond_materials,
                                      bond_material_index=np.arange(bonds.shape[0]))
    simulation = bondem.Simulation(model, state)
    steps = int(math.ceil(duration / simulation.time_step))
    peak = 0.0
    simulation.step(0)
    for _ in range(steps):
        simulation.step(1)
        # The loads on the stopped layer are what the target must supply (with opposite sign).
        peak = max(peak, float(np.linalg.norm(simulation.force[bottom].sum(axis=0))))
    intact = state.bond_active
    return {"broken_bond_fraction": float(1.0 - intact.mean()),
            "largest_fragment_fraction": _largest_fragment(model, intact),
            "peak_wall_force": peak,
            "specific_energy": 0.5 * speed ** 2}


def _largest_fragment(model, intact):
    """Mass fraction of the largest set of particles connected by intact bonds."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    n = model.n_particles
    pairs = model.bond_pairs[intact]
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, label = connected_components(graph, directed=False)
    mass = np.bincount(label, weights=model.mass)
    return float(mass.max() / model.mass.sum())

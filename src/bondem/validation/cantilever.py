"""Cantilever of bonded spheres under a static end load vs Timoshenko and Euler-Bernoulli.

A straight chain of N bonds (length L = N L0) is clamped at its first sphere and loaded
by a transverse force P at the centre of its last sphere; gravity is off and local
damping brings it to rest. References, with the bond's E, G, A = pi R_b^2, I = pi R_b^4/4:
    Euler-Bernoulli:  w = P L^3 / (3 E I)
    Timoshenko:       w = P L^3 / (3 E I) + P L / (kappa G A),  kappa = 1
Why kappa = 1 and why the discrete chain matches the continuum: in equilibrium every bond
carries the shear P and at its centre the moment P (L - x_c); its bending spring E I/L0
turns the nodes by the midpoint rule of M/(E I) (exact for a linear moment), its shear
spring G A/L0 adds P L0/(G A) per bond, and v_rel's (w_i + w_j) x r / 2 term makes the
deflection the trapezoid integral of the rotations, which differs from the continuum by
1/(4 N^2) relative. Chen et al. (2022, Granular Matter 24) study the same beam for several
slenderness ratios L/d_b and bond/particle diameter ratios d_b/d_p.
A third row compares with that discrete answer, the Timoshenko deflection with its bending
part times (1 - 1/(4 N^2)), to a tighter tolerance. The Euler-Bernoulli row is a
pass/fail check only for slender beams, where the shear term is below a quarter of the
tolerance; for short thick beams it is shown as information
(the shear term is then the point: Timoshenko agrees, Euler-Bernoulli does not).
"""
import numpy as np

import bondem

from .core import CaseResult, Plot, Series, case, compare, info


def tip_deflection(p, compat, n_bonds, bond_diameter):
    """Simulated static tip deflection (m) of the cantilever, and the steps taken."""
    spacing, run = p["particles"]["spacing"], p["run"]
    n = n_bonds + 1
    position = np.column_stack([np.arange(n) * spacing, np.zeros(n), np.zeros(n)])
    fixed = np.zeros(n, bool)
    fixed[0] = True
    force = np.zeros((n, 3))
    force[-1, 1] = p["load"]["force"]
    particle = bondem.Material(density=p["material"]["density"],
                               young_modulus=p["material"]["young_modulus"])
    binder = bondem.BondMaterial(young_modulus=p["bond"]["young_modulus"],
                                 poisson_ratio=p["bond"]["poisson_ratio"], breakage="none")
    model, state = bondem.make_system(
        position, p["particles"]["radius"], particle, fixed=fixed, external_force=force,
        bonds=[[k, k + 1] for k in range(n_bonds)], bond_diameter=bond_diameter,
        bond_material=binder, damping=run["damping"])
    sim = bondem.Simulation(model, state, safety_factor=run["safety_factor"],
                            musen_compat=compat == "musen")
    previous = np.inf
    deflection = 0.0
    for _ in range(run["max_chunks"]):
        sim.step(run["chunk"])
        deflection = state.position[-1, 1]
        if (abs(deflection - previous) < run["converged_change"] * abs(deflection)
                and np.abs(state.velocity).max() < run["converged_speed"]):
            break
        previous = deflection
    return deflection, state.step


@case("cantilever", quick=True)
def run(p, compat, quick=False):
    """Cantilever of bonded spheres: static tip deflection vs Timoshenko / Euler-Bernoulli."""
    young, poisson = p["bond"]["young_modulus"], p["bond"]["poisson_ratio"]
    shear_modulus = young / (2 * (1 + poisson))
    load, spacing = p["load"]["force"], p["particles"]["spacing"]
    particle_diameter = 2 * p["particles"]["radius"]
    tolerance = p["run"]["tolerance"]
    rows, points = [], []
    for conf in p["configurations"]:
        if quick and not conf["quick"]:
            continue
        n_bonds, ratio = conf["n_bonds"], conf["ratio"]
        bond_diameter = ratio * particle_diameter
        length = n_bonds * spacing
        radius = bond_diameter / 2
        area, second = np.pi * radius ** 2, np.pi * radius ** 4 / 4
        euler = load * length ** 3 / (3 * young * second)
        timoshenko = euler + load * length / (shear_modulus * area)
        deflection, steps = tip_deflection(p, compat, n_bonds, bond_diameter)
        label = f"L/d_b={length / bond_diameter:g}, d_b/d_p={ratio:g}"
        rows.append(compare("cantilever", f"tip deflection Timoshenko (m) {label}",
                            timoshenko, deflection, tolerance,
                            note=f"{steps} steps to equilibrium"))
        # The chain's own exact answer: the bending part short by 1/(4 N^2) (trapezoid
        # integral of midpoint-rule rotations); a sharp check of the bond's springs.
        discrete = euler * (1 - 1 / (4 * n_bonds ** 2)) + (timoshenko - euler)
        rows.append(compare("cantilever", f"tip deflection discrete chain (m) {label}",
                            discrete, deflection, p["run"]["tolerance_discrete"]))
        shear_share = (timoshenko - euler) / timoshenko
        if shear_share < tolerance / 4:
            rows.append(compare("cantilever", f"tip deflection Euler-Bernoulli (m) {label}",
                                euler, deflection, tolerance))
        else:
            rows.append(info("cantilever", f"tip deflection Euler-Bernoulli (m) {label}",
                             euler, deflection,
                             f"shear term is {shear_share:.1%} of Timoshenko's deflection"))
        points.append((length / bond_diameter, deflection / timoshenko,
                       discrete / timoshenko, euler / timoshenko))
    points.sort()
    x = [q[0] for q in points]
    plot = Plot("Cantilever tip deflection / Timoshenko", "slenderness L / d_b",
                "w / w_Timoshenko", [
                    Series("bondem", x, [q[1] for q in points], "o"),
                    Series("discrete chain (exact)", x, [q[2] for q in points], "x"),
                    Series("Euler-Bernoulli", x, [q[3] for q in points], "s"),
                    Series("Timoshenko", [min(x), max(x)] if x else [], [1.0, 1.0] if x else [],
                           "--")], logx=True)
    return CaseResult(rows, [plot])

"""An adhesive agglomerate without bonds (JKR contacts only) dropped on a plate at a range
of speeds: below a critical speed it sticks to the plate and stays whole, above it
fragments. Writes docs/adhesive_drop.json and prints a table; docs/contact_jkr.md reports
the measured critical speeds against the closed-form sticking speed of one primary
particle (the JKR energy balance, Johnson & Pollock 1994; Thornton & Ning 1998).

    python scripts/adhesive_drop.py [--diameter 1.6e-4] [--speeds 0.05,0.1,...]

Primary particles: radius 5 um, density 2500 kg/m^3, E = 1e8 Pa, nu = 0.3, restitution
0.5, friction 0.3, surface energy 0.05 J/m^2; the agglomerate: a random packing of a sphere
pressed to 2e5 Pa by servo walls (lab.specimen.make_specimen, seed 1), then settled under
its JKR contacts (local damping 0.7, 40 us). The plate is of the same material.
Fragments: particles joined by loaded contacts (scipy's connected
components); "whole": the largest fragment keeps 90 % of the particles; "stuck": the
agglomerate's centre of mass moves away from the plate at the end at less than 5 % of
the impact speed.
"""
import argparse
import json
import math
import time
from pathlib import Path

import numpy as np
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

import bondem
from bondem.contacts import ContactSettings
from bondem.lab.specimen import make_specimen
from bondem.walls import PlaneWall

RADIUS, W, E, NU, RHO = 5e-6, 0.05, 1e8, 0.3, 2500.0


def sticking_speed(r_star, m_star, e_star, w):
    """The JKR energy balance: 1/2 m* v^2 = 7.09 (w^5 R*^4 / E*^2)^(1/3) (m/s), and
    Thornton & Ning's 1.84 (F_c^5 / (E*^2 R* m*^3))^(1/6), F_c = 3/2 pi w R*."""
    loss = 7.09 * (w ** 5 * r_star ** 4 / e_star ** 2) ** (1 / 3)
    f_c = 1.5 * math.pi * w * r_star
    return (math.sqrt(2 * loss / m_star),
            1.84 * (f_c ** 5 / (e_star ** 2 * r_star * m_star ** 3)) ** (1 / 6))


def fragments(state, n):
    pairs = state.extra["contact_pairs"]
    loaded = pairs[np.any(state.extra["contact_force"] != 0.0, axis=1)]
    graph = coo_matrix((np.ones(len(loaded)), (loaded[:, 0], loaded[:, 1])), shape=(n, n))
    _, labels = connected_components(graph, directed=False)
    return np.bincount(labels).max() / n


def relax(specimen, time_span=4e-5):
    """The consolidated packing settled under its own JKR contacts (local damping 0.7,
    no wall): positions (N,3) m at rest."""
    model, state = specimen.system(damping=0.7)
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            safety_factor=0.3)
    sim.run(until=time_span)
    return state.position.copy()


def drop(specimen, position, material, speed, gap):
    model, state = specimen.system(velocity=np.tile([0.0, 0.0, -speed],
                                                    (specimen.n_particles, 1)))
    state.position[:] = position
    state.position[:, 2] += -state.position[:, 2].min() + RADIUS + gap
    sim = bondem.Simulation(model, state, contact=ContactSettings(model="jkr"),
                            walls=[PlaneWall([0, 0, 0], [0, 0, 1], material)],
                            safety_factor=0.3)
    height = float(state.position[:, 2].max() - state.position[:, 2].min())
    # the fall to the plate, then the time to cross its own height three times
    end = gap / speed + 3.0 * height / speed + 2e-5
    sim.run(until=end)
    vz = float(np.mean(state.velocity[:, 2]))
    return {"speed": speed, "largest_fragment": fragments(state, model.n_particles),
            "centre_velocity_z": vz, "stuck": vz <= 0.05 * speed,
            "steps": int(state.step)}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--diameter", type=float, default=1.6e-4)
    parser.add_argument("--speeds", default="8,4,2,1,0.5,0.25")
    parser.add_argument("--out", default="docs/adhesive_drop.json")
    args = parser.parse_args()
    material = bondem.Material(density=RHO, young_modulus=E, poisson_ratio=NU,
                               restitution=0.5, friction=0.3, surface_energy=W)
    start = time.time()
    specimen = make_specimen("sphere", [args.diameter], particle_radius=RADIUS, seed=1,
                             material=material, bond_material=None, contact_model="jkr",
                             consolidation_stress=2e5)
    position = relax(specimen)
    print(specimen.notes, f"relaxed, {time.time() - start:.0f} s", flush=True)
    e_pp = E / (2 * (1 - NU ** 2))
    mass = RHO * 4 / 3 * math.pi * RADIUS ** 3
    closed = {"particle_particle": sticking_speed(RADIUS / 2, mass / 2, e_pp, W),
              "particle_wall": sticking_speed(RADIUS, mass, e_pp, W)}
    rows = []
    for speed in (float(v) for v in args.speeds.split(",")):
        row = drop(specimen, position, material, speed, 0.2 * RADIUS)
        rows.append(row)
        print(f"{speed:6.3f} m/s: largest fragment {row['largest_fragment']:.3f}, centre "
              f"vz {row['centre_velocity_z']:+.4f} m/s, {'stuck' if row['stuck'] else 'rebounds'}"
              f" ({row['steps']} steps, {time.time() - start:.0f} s)", flush=True)
    out = {"particles": specimen.n_particles, "diameter": args.diameter, "radius": RADIUS,
           "surface_energy": W, "young_modulus": E, "poisson_ratio": NU, "density": RHO,
           "closed_form_sticking_speed": {k: {"jkr_energy_balance": v[0],
                                              "thornton_ning": v[1]}
                                         for k, v in closed.items()},
           "drops": rows}
    Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    print(json.dumps(out["closed_form_sticking_speed"], indent=1))


if __name__ == "__main__":
    main()

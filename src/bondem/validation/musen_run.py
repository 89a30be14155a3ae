"""``--compat musen``: bondem's MUSEN mode against the NumPy transcription of MUSEN.

A cluster of 6 bonded spheres (an octahedron, 12 bonds) tumbles about an oblique axis,
is stretched radially and each sphere spins about its own random axis (twist and
bending of every bond). bondem runs it with ``Simulation(musen_compat=True)`` and the
transcription (``musen_reference.musen_run``: MUSEN's rotation matrix, twist sense, no
re-projection, start-up step and integrator) runs the same steps. With --compat musen the
final positions, velocities, spins and stored bond vectors must agree to the tolerance;
in SPEC mode the same difference is shown for information (it measures how far the SPEC's
numerics are from MUSEN's on this run). See docs/musen_compat.md.
"""
import numpy as np

from .core import CaseResult, case, compare, info
from .musen_reference import musen_run

QUANTITIES = ("position", "velocity", "angular_velocity", "tangential_force",
              "normal_moment", "tangential_moment")


def octahedron_cluster(radius, p):
    """(model, state) of the tumbling, stretched, twisted 6-sphere cluster (SI units).

    p: the ``cluster`` table of musen.toml (optional keys breakage, normal_strength and
    tangential_strength, Pa, set the bond material's breakage; default unbreakable).
    """
    import bondem
    directions = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1],
                           [0, 0, -1]], float)
    # Edge length 2 radius: neighbours touch; opposite corners are not bonded.
    position = directions * (2.0 * radius / np.sqrt(2.0))
    bonds = [(a, b) for a in range(6) for b in range(a + 1, 6)
             if abs(np.dot(directions[a], directions[b])) < 0.5]
    material = bondem.Material(density=p["density"], young_modulus=p["young_modulus"],
                               poisson_ratio=p["poisson_ratio"], name="spheres")
    binder = bondem.BondMaterial(young_modulus=p["young_modulus"],
                                 poisson_ratio=p["poisson_ratio"],
                                 breakage=p.get("breakage", "none"),
                                 normal_strength=p.get("normal_strength", np.inf),
                                 tangential_strength=p.get("tangential_strength", np.inf),
                                 name="binder")
    model, state = bondem.make_system(position, radius, material, bonds=np.array(bonds),
                                      bond_diameter=p["bond_diameter_ratio"] * 2 * radius,
                                      bond_material=binder)
    return model, state


def set_motion(model, state, dt, p):
    """Give the cluster its tumbling, stretching and spinning velocities for step dt (s)."""
    rng = np.random.default_rng(p["seed"])
    per_step = 1.0 / (1000.0 * dt)           # "per 1000 steps" -> per second
    omega = p["spin"] * per_step * np.array([1.0, 2.0, 3.0]) / np.sqrt(14.0)
    x = state.position
    speed = np.linalg.norm(omega) * np.linalg.norm(x, axis=1).max()
    # Rigid tumbling + radial stretch + random relative motion (stretch, shear, bending);
    # random spins about random axes twist and bend every bond.
    state.velocity[:] = (np.cross(omega, x) + p["stretch"] * per_step * x
                         + p["perturbation"] * speed * rng.standard_normal(x.shape))
    state.angular_velocity[:] = omega + p["spin_random"] * np.linalg.norm(omega) \
        * rng.standard_normal(x.shape)


def run_both(radius, p, steps, compat=True):
    """bondem (musen_compat=compat) and the MUSEN transcription after ``steps`` steps.

    Returns (bondem results dict, MUSEN results dict, dt in s).
    """
    import bondem
    model, state = octahedron_cluster(radius, p)
    dt = bondem.Simulation(model, state.copy()).time_step
    set_motion(model, state, dt, p)
    reference = musen_run(model, state, dt, steps)
    sim = bondem.Simulation(model, state, time_step=dt, musen_compat=compat)
    sim.step(steps)
    s = sim.state
    ours = dict(position=s.position, velocity=s.velocity,
                angular_velocity=s.angular_velocity,
                tangential_force=s.bond_tangential_force,
                normal_moment=s.bond_normal_moment,
                tangential_moment=s.bond_tangential_moment, active=s.bond_active,
                break_time=s.bond_break_time)
    return ours, reference, dt


def largest_difference(ours, reference, name):
    """max |bondem - MUSEN| / max |MUSEN| over all entries of array ``name``."""
    scale = max(float(np.abs(reference[name]).max()), 1e-300)
    return float(np.abs(ours[name] - reference[name]).max()) / scale



@case("musen", quick=True)
def run(p, compat, quick=False):
    """MUSEN mode: a tumbling, stretched, twisted cluster against MUSEN's scheme in NumPy."""
    rows = []
    steps = p["run"]["steps_quick" if quick else "steps"]
    tolerance = p["run"]["tolerance"]
    for radius in p["cluster"]["radii"]:
        ours, reference, dt = run_both(radius, p["cluster"], steps, compat == "musen")
        label = f"L0 = {2 * radius:g} m, {steps} steps"
        for name in QUANTITIES:
            difference = largest_difference(ours, reference, name)
            quantity = f"{label}: max |{name} - MUSEN| / max |MUSEN|"
            if compat == "musen":
                rows.append(compare("musen", quantity, 0.0, difference, tolerance,
                                    absolute=True))
            else:
                rows.append(info("musen", quantity, 0.0, difference,
                                 "SPEC mode vs MUSEN's numerics (run with --compat musen "
                                 "to check them)", absolute=True))
    return CaseResult(rows)

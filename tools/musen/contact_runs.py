"""Reference runs of MUSEN's adhesive contact models, made with cmusen 1.74.2.

    python tools/musen/contact_runs.py CMUSEN OUT NAME [NAME ...]

Each NAME below is a 3x3x3 cluster of unbonded spheres (radius 1 mm, 10 um apart) with
random velocities and spins, falling on the plane z = 0 under gravity: pairs collide,
stick or bounce, and the lowest layer hits the wall. make_refdata.write (../shared/tools/
musen) writes the scene with Hertz-Mindlin contacts; here the contact models replace
them: the cmusen script's MODEL_PP / MODEL_PW, MUSEN's material its surface energy
(property 11), the bondem scene its contact_model and material keys. compare.toml then
compares every particle's position, velocity and spin (make_refdata's contact scenes
keep one loose row). refresh_runs.py adapts the MUSEN files to 1.74's text import, runs
cmusen in OUT/NAME and writes make_refdata's CSV files there.
"""
import math
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import refresh_runs  # noqa: E402  (this folder; it imports ../shared's make_refdata)

make_refdata = refresh_runs.make_refdata
P_SURFACE_ENERGY = 11   # Databases/MaterialsDatabase/DefinesMDB.h, PROPERTY_SURFACE_ENERGY
P_SURFACE_TENSION = 13  # PROPERTY_SURFACE_TENSION
MUSEN_TAG = "v1.74.2"
MUSEN_VDW_DMIN = 7.5e-10  # ModelPPHertzMindlinVdW.cpp's Dmin (m)


def falling_cluster(title, story, seed, speed, spin, steps=5000):
    """27 unbonded spheres of radius 1 mm on a 2.01 mm lattice whose lowest layer stands
    5 um above the plane z = 0; velocities uniform in [-speed, speed] m/s plus -speed in
    z, spins in [-spin, spin] rad/s, from default_rng(seed); gravity -9.81 m/s^2 in z."""
    x, _ = make_refdata.lattice(3, 0.00201)
    x[:, 2] += 1e-3 + 5e-6
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1.0, 1.0, (27, 3)) * speed
    v[:, 2] -= speed
    w = rng.uniform(-1.0, 1.0, (27, 3)) * spin
    return dict(title=title, x=x, v=v, w=w, radius=np.full(27, 1e-3), pairs=np.zeros((0, 2), dtype=int),
                bond_diameter=1e-3, dt=1e-7, steps=steps, save_steps=250, criterion=0,
                strength=1e30, gravity=(0.0, 0.0, -9.81), contacts=True,
                story=f"27 unbonded spheres (radius 1 mm) on a 3x3x3 lattice of spacing "
                      f"2.01 mm (10 um gaps), the lowest layer 5 um above the plane z = 0. "
                      f"Velocities uniform in [-{speed}, {speed}] m/s per component plus "
                      f"-{speed} m/s in z and spins in [-{spin}, {spin}] rad/s, "
                      f"numpy.random.default_rng({seed}), velocities drawn first (27 x 3), "
                      f"then spins (27 x 3); gravity -9.81 m/s^2 in z. " + story)


# name: (scene, MODEL_PP, MODEL_PW, MUSEN surface energy J/m^2 (Popov's JKR: its surface
# tension, property 13), bondem contact model and material keys)
MODELS = {
    "jkr_cluster": (
        lambda: falling_cluster("3x3x3 cluster of adhesive spheres (JKR) falling on a plane "
                                "(MUSEN 1.74.2, ModelPPJKR, ModelPWJKR)",
                                "Surface energy 5 J/m^2.", 20261210, 0.1, 50.0),
        "ModelPPJKR", "ModelPWJKR", 5.0, "jkr", {"surface_energy": 5.0}),
    "vdw_cluster": (
        lambda: falling_cluster("3x3x3 cluster of spheres with van der Waals attraction "
                                "falling on a plane (MUSEN 1.74.2, ModelPPHertzMindlinVdW, "
                                "ModelPWHertzMindlin)",
                                "Surface energy 0.5 J/m^2 (MUSEN's Hamaker constant "
                                "24 pi Dmin^2 w, Dmin = 7.5e-10 m).", 20261211, 0.1, 50.0),
        "ModelPPHertzMindlinVdW", "ModelPWHertzMindlin", 0.5, "vdw",
        {"hamaker_constant": 24 * math.pi * MUSEN_VDW_DMIN * MUSEN_VDW_DMIN * 0.5}),
    "popov_cluster": (
        lambda: falling_cluster("3x3x3 cluster of adhesive spheres (Popov's JKR) falling on "
                                "a plane (MUSEN 1.74.2, ModelPPPopovJKR, ModelPWPopovJKR)",
                                "Surface tension (MUSEN's w of this model) 5 J/m^2.",
                                20261212, 0.1, 50.0),
        "ModelPPPopovJKR", "ModelPWPopovJKR", 5.0, "popov_jkr", {"surface_energy": 5.0}),
}
PROPERTY = {"popov_cluster": P_SURFACE_TENSION}


def compare_rows(n):
    """compare.toml rows: every particle's position, velocity and spin."""
    items = []
    for k in range(n):
        for q, quantity in (("", "particles/position"), ("v", "particles/velocity"),
                            ("w", "particles/angular_velocity")):
            for c, axis in enumerate("xyz"):
                column = f"{q}{axis}{k}" if q else f"{axis}{k}"
                items.append(f'[[compare]]\nfile = "musen_particles.csv"\n'
                             f'time_column = "time"\ncolumn = "{column}"\n'
                             f'quantity = "{quantity}"\nindex = [{k}, {c}]\n'
                             f'tolerance = 1e-9\n')
    return 'scene = "scene.toml"\n\n' + "\n".join(items)


def write(name, folder):
    """Write scene ``name`` into ``folder`` (make_refdata.write, then the contact model)."""
    scene, pp, pw, surface_energy, model, keys = MODELS[name]
    s = refresh_runs.write_scene(name, scene, folder)
    toml = (folder / "scene.toml").read_text()
    toml = toml.replace("[simulation]\n", "[simulation]\nmusen_version = \"1.74.2\"  "
                                          "# the release the run was made with\n")
    toml = toml.replace('contact_model = "hertz_mindlin"', f'contact_model = "{model}"')
    toml = toml.replace("rolling_friction = 0.0\n", "rolling_friction = 0.0\n" + "".join(
        f"{k} = {make_refdata.full(v)}\n" for k, v in keys.items()), 1)
    # no bonds: the scene has no bond section (bondem needs no bonds file)
    toml = re.sub(r"\n\[bonds\]\nfile = \"bonds.csv\"\n", "\n", toml)
    (folder / "scene.toml").write_text(toml)
    (folder / "bonds.csv").unlink()
    lines = (folder / "musen_scene.txt").read_text().splitlines()
    prop = PROPERTY.get(name, P_SURFACE_ENERGY)
    lines = [line + f" {prop} {make_refdata.full(surface_energy)}"
             if line.startswith("32 solid solid ") else line for line in lines]
    (folder / "musen_scene.txt").write_text("\n".join(lines) + "\n")
    script = (folder / "musen_script.txt").read_text()
    script = script.replace("MODEL_PP ModelPPHertzMindlin\n", f"MODEL_PP {pp}\n")
    script = script.replace("MODEL_PW ModelPWHertzMindlin\n", f"MODEL_PW {pw}\n")
    (folder / "musen_script.txt").write_text(script)
    (folder / "compare.toml").write_text(compare_rows(len(s["x"])))
    text = (folder / "SCENE.md").read_text()
    text = refresh_runs.credit(text, name, "contact_runs.py", MUSEN_TAG)
    text = re.sub(r"- particle-particle: `ModelPPHertzMindlin`.*?\n",
                  f"- particle-particle: `{pp}`; particle-wall: `{pw}` (MUSEN {MUSEN_TAG}); "
                  f"material property {prop} ({'surface tension' if prop == 13 else 'surface energy'}) "
                  f"{surface_energy:g} J/m^2; bondem: "
                  f"`contact_model = \"{model}\"`, "
                  + ", ".join(f"`{k} = {v!r}`" for k, v in keys.items())
                  + " (`bondem validate --compat musen` compares in MUSEN's numerics).\n",
                  text)
    text = text.replace("- contacts: Hertz-Mindlin particle-particle and particle-wall,",
                        "- contacts: the models below, particle-particle and particle-wall,")
    text = re.sub(r"- bonds: 0, .*?\n", "- bonds: none (no `bonds.csv`).\n", text)
    text = re.sub(r"- `scene.toml`, `particles.csv`, `bonds.csv`: .*?\n",
                  "- `scene.toml`, `particles.csv`: the same scene for bondem (docs/scene.md); "
                  "`compare.toml`: bondem's refdata format, every particle's position, "
                  "velocity and spin in every frame, tolerance 1e-9 of the largest value "
                  "(met with `--compat musen`; SPEC mode's rows are information).\n", text)
    (folder / "SCENE.md").write_text(text)
    return s


def main(cmusen, out, names):
    refresh_runs.make_runs(cmusen, out, names, write, ("scene.toml", "particles.csv", "compare.toml", "SCENE.md"))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])

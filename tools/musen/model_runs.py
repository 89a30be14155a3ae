"""Reference runs of MUSEN's other solid bond models, made with cmusen 1.74.2 (the models
exist only in the releases after 1.70.0).

    python tools/musen/model_runs.py CMUSEN OUT NAME [NAME ...]

Each NAME below is a scene of ../shared/tools/musen/make_refdata.py's kind (a 3x3x3 bonded
cluster with random velocities and spins) whose bonds use one of MUSEN's models. The scene
is written by make_refdata.write, then given its model: the bondem scene's bond material
gets the model's keys (and musen_version 1.74.2), MUSEN's bond material its
YIELD_STRENGTH (property 15) where the model reads one, the cmusen script MODEL_SB and
MODEL_SB_PARAMS. (The packaged runs keep the bondem scene, MUSEN's inputs and the CSV
files but musen_bonds.csv.) refresh_runs.py adapts the MUSEN files to 1.74's text import, runs cmusen
in OUT/NAME and writes make_refdata's CSV files there.
"""
import re
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import refresh_runs  # noqa: E402  (this folder; it imports ../shared's make_refdata)

make_refdata = refresh_runs.make_refdata
P_YIELD_STRENGTH = 15   # Databases/MaterialsDatabase/DefinesMDB.h, PROPERTY_YIELD_STRENGTH
MUSEN_TAG = "v1.74.2"


def cluster(title, story, seed, speed, spin, steps=5000, strength=None):
    """make_refdata's kelvin_cluster scene, velocities uniform in [-speed, speed] m/s and
    spins in [-spin, spin] rad/s from default_rng(seed); strength (Pa): normal and
    tangential, with the combined criterion (None: no stress breakage)."""
    x, pairs = make_refdata.lattice(3, 0.002)
    rng = np.random.default_rng(seed)
    v = rng.uniform(-1.0, 1.0, (27, 3)) * speed
    w = rng.uniform(-1.0, 1.0, (27, 3)) * spin
    return dict(title=title, x=x, v=v, w=w, radius=np.full(27, 1e-3), pairs=pairs,
                bond_diameter=1e-3, dt=1e-7, steps=steps, save_steps=250,
                criterion=0 if strength is None else 1,
                strength=1e30 if strength is None else strength,
                story=f"Velocities and spins: every component uniform in [-{speed}, {speed}] "
                      f"m/s and [-{spin}, {spin}] rad/s, numpy.random.default_rng({seed}), "
                      f"velocities drawn first (27 x 3), then spins (27 x 3). " + story)


# name: (scene, MUSEN model, its MODEL_SB_PARAMS, YIELD_STRENGTH or None, bondem keys)
MODELS = {
    "plastic_cluster": (
        lambda: cluster("3x3x3 cluster of elastic-perfectly plastic bonds, yielding in "
                        "tension, compression and shear, some breaking by strain "
                        "(MUSEN 1.74.2, ModelSBElasticPerfectlyPlastic)",
                        "Yield strength 1.5e5 Pa, compressive yield 1.3 times the tensile, "
                        "tangential yield on, fracture strains 0.02 in tension and 0.03 in "
                        "compression.", 20261203, 0.3, 100.0),
        "ModelSBElasticPerfectlyPlastic",
        "FRACTURE_STRAIN_TENSION 0.02 FRACTURE_STRAIN_COMPRESSION 0.03 TANGENTIAL_YIELD 1 "
        "RATIO_COMPR_TENSILE_YIELD 1.3", 1.5e5,
        {"model": '"elastic_plastic"', "yield_strength": "150000.0",
         "compressive_yield_ratio": "1.3", "tangential_yield": "true",
         "fracture_strain": "0.02", "compressive_fracture_strain": "0.03"}),
    "creep_cluster": (
        lambda: cluster("3x3x3 cluster of creep bonds, yielding and creeping, breaking by "
                        "stress (MUSEN 1.74.2, ModelSBCreep)",
                        "Yield strength 2e5 Pa, compressive yield 1.2 times the tensile, "
                        "tangential yield on, creep A = 1e-4 1/(s Pa^m), m = 0.8, fracture "
                        "strain 0.02 in tension (none in compression), stress fracture on "
                        "(FRACTURE_BY_STRESS 1) with strengths 2.6e5 Pa.", 20261204, 0.3,
                        100.0, strength=2.6e5),
        "ModelSBCreep",
        "FRACTURE_STRAIN_TENSION 0.02 FRACTURE_STRAIN_COMPRESSION 0 TANGENTIAL_YIELD 1 "
        "RATIO_COMPR_TENSILE_YIELD 1.2 CREEP_PARAMATER_A 0.0001 CREEP_PARAMATER_m 0.8 "
        "FRACTURE_BY_STRESS 1", 2e5,
        {"model": '"creep"', "yield_strength": "200000.0", "compressive_yield_ratio": "1.2",
         "tangential_yield": "true", "fracture_strain": "0.02", "creep_rate": "0.0001",
         "creep_exponent": "0.8"}),
    "weakening_cluster": (
        lambda: cluster("3x3x3 cluster of weakening bonds with weakening factor 0 (each "
                        "yield drops the stress to zero), breaking by strain "
                        "(MUSEN 1.74.2, ModelSBWeakening)",
                        "Yield strength 5e4 Pa, WEAKENING_FACTOR 0 (MUSEN's draws from "
                        "C rand() then do not matter), breakage strain 0.002 in tension and "
                        "0.004 in compression (COMPRESSIVE_BREAK 1).", 20261205, 0.3, 100.0),
        "ModelSBWeakening",
        "CONSIDER_BREAKAGE 1 COMPRESSIVE_BREAK 1 BREAKAGE_STRAIN 0.002 WEAKENING_FACTOR 0",
        5e4,
        {"model": '"weakening"', "yield_strength": "50000.0", "fracture_strain": "0.002",
         "compressive_fracture_strain": "0.004", "weakening_factor": "0.0"}),
    "aerogel_cluster": (
        lambda: cluster("3x3x3 cluster of aerogel bonds crushed past their compressive "
                        "plastic strain and broken in tension past a hardening branch "
                        "(MUSEN 1.74.2, ModelSBAerogel)",
                        "Plastic strains 0.0008 in compression and 0.001 in tension, "
                        "softness ratios -1 in compression (the force falls to zero at "
                        "-0.0016: crushed) and +0.5 in tension (hardening), hardness 0.2 and "
                        "0.3, breaking strain 0.0013 (reached at a strain of 0.0016).",
                        20261206, 0.3, 100.0),
        "ModelSBAerogel",
        "PLASTIC_STRAIN_COMPR 0.0008 PLASTIC_STRAIN_TENS 0.001 SOFTNESS_RATIO_COMPR -1 "
        "SOFTNESS_RATIO_TENS 0.5 BREAK_STRAIN_TENS 0.0013 HARDNESS_RATIO_COMPR 0.2 "
        "HARDNESS_RATIO_TENS 0.3", None,
        {"model": '"aerogel"', "compressive_plastic_strain": "0.0008",
         "tensile_plastic_strain": "0.001", "compressive_softness": "-1.0",
         "tensile_softness": "0.5", "tensile_break_strain": "0.0013",
         "compressive_hardness": "0.2", "tensile_hardness": "0.3"}),
    "linear_plastic_cluster": (
        lambda: cluster("3x3x3 cluster of MUSEN's linear plastic bonds with E > 2 Pa, which "
                        "MUSEN runs as its elastic bond, breaking by the combined "
                        "criterion (MUSEN 1.74.2, ModelSBLinearPlastic)",
                        "KLoad 1e6 and KUnload 3e6 (used by MUSEN only for a bond Young's "
                        "modulus of 2 Pa or less), strengths 2.5e5 Pa.", 20261207, 0.3,
                        100.0, strength=2.5e5),
        "ModelSBLinearPlastic", "CONSIDER_BREAKAGE 1 KLoad 1000000 KUnload 3000000", None,
        {}),
    "concrete_cluster": (
        lambda: cluster("3x3x3 cluster of MUSEN's plastic concrete bonds, whose defects "
                        "(a repulsive normal force, a tangential force L0 / 1 m off) make "
                        "it fly apart (MUSEN 1.74.2, ModelSBPlasticConcrete)",
                        "Yield strength 2e5 Pa, CONSIDER_BREAKAGE 1; the run is kept to "
                        "show that --compat musen reproduces MUSEN's defects, not as "
                        "physics.", 20261208, 0.3, 100.0, steps=1000),
        "ModelSBPlasticConcrete", "CONSIDER_BREAKAGE 1", 2e5,
        {"model": '"concrete"', "yield_strength": "200000.0"}),
}


def write(name, folder):
    """Write scene ``name`` into ``folder`` (make_refdata.write, then the model)."""
    scene, musen_model, parameters, yield_strength, keys = MODELS[name]
    s = refresh_runs.write_scene(name, scene, folder)
    toml = (folder / "scene.toml").read_text()
    # not musen_compat: the same parameters mean the same in bondem's own law, so SPEC
    # mode runs it too (info rows in `bondem validate`, checked with --compat musen)
    toml = toml.replace("[simulation]\n", "[simulation]\nmusen_version = \"1.74.2\"  "
                                          "# the release the run was made with\n")
    toml = re.sub(r'(breakage = "[a-z]+"\n)', lambda match: match.group(1) + "".join(
        f"{k} = {v}\n" for k, v in keys.items()), toml)
    (folder / "scene.toml").write_text(toml)
    if yield_strength is not None:
        lines = (folder / "musen_scene.txt").read_text().splitlines()
        lines = [line + f" {P_YIELD_STRENGTH} {make_refdata.full(yield_strength)}"
                 if line.startswith("32 bond bond ") else line for line in lines]
        (folder / "musen_scene.txt").write_text("\n".join(lines) + "\n")
    script = (folder / "musen_script.txt").read_text()
    script = re.sub(r"MODEL_SB .*\nMODEL_SB_PARAMS .*\n",
                    f"MODEL_SB {musen_model}\nMODEL_SB_PARAMS {parameters}\n", script)
    (folder / "musen_script.txt").write_text(script)
    text = (folder / "SCENE.md").read_text()
    text = refresh_runs.credit(text, name, "model_runs.py", MUSEN_TAG)
    text = re.sub(r"- solid bond: `ModelSBElastic`.*?\n",
                  f"- solid bond: `{musen_model}` (MUSEN {MUSEN_TAG}), `MODEL_SB_PARAMS "
                  f"{parameters}`"
                  + (f", bond material YIELD_STRENGTH {yield_strength:g} Pa" if
                     yield_strength is not None else "")
                  + "; bondem: " + ", ".join(f"`{k} = {v}`" for k, v in keys.items())
                  + " (`bondem validate --compat musen` compares in MUSEN's numerics).\n",
                  text)
    (folder / "SCENE.md").write_text(text)
    return s


def main(cmusen, out, names):
    refresh_runs.make_runs(cmusen, out, names, write, ("scene.toml", "particles.csv", "bonds.csv", "compare.toml", "SCENE.md"))


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])

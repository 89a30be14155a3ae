"""Lab spec files (bondem.lab.spec): the settings a spec without [test] gets are the
defaults docs/lab.md documents; each specimen key reaches the specimen; every bad value
stops with an InputError naming the file and the key."""
import re
from pathlib import Path

import numpy as np
import pytest

from bondem.errors import InputError
from bondem.lab import spec as spec_module
from bondem.lab.spec import load_spec

DOCS = Path(__file__).resolve().parents[1] / "docs" / "lab.md"
MATERIALS = ("[specimen.material]\ndensity = 2500.0\nyoung_modulus = 1e8\n"
             "[specimen.bond_material]\nyoung_modulus = 2e8\n")
LATTICE = "[specimen]\nlattice = [3, 2, 4]\nradius = 1e-3\ndiameter_ratio = 0.4\n"


def write(tmp_path, text, name="spec.toml"):
    path = tmp_path / name
    path.write_text(text)
    return path


def documented_defaults():
    """{key: default text} of docs/lab.md's settings table (rows naming several keys
    split into one entry each)."""
    text = DOCS.read_text()
    table = text[text.index("### Settings (`[test]`"):]
    table = table[:table.index("\n\n", table.index("| key |"))]
    out = {}
    for row in table.splitlines()[3:]:
        cells = [c.strip() for c in row.strip("|").split("|")]
        keys = re.findall(r"`(\w+)`", cells[0])
        values = [v.strip() for v in re.split(r",(?![^\[]*\])", cells[1])]
        for key, value in zip(keys, values if len(values) == len(keys) else [cells[1]] * 9):
            out[key] = value
    return out


def test_a_spec_without_test_gets_the_documented_defaults(tmp_path):
    _, settings, _ = load_spec(write(tmp_path, LATTICE + MATERIALS))
    documented = documented_defaults()
    assert len(documented) == 24
    for key, text in documented.items():
        value = getattr(settings, key)
        plain = re.fullmatch(r"[-+0-9.e]+|\[[-+0-9.e, ]+\]|[a-z_0-9]+", text)
        if text.startswith("["):
            assert value == tuple(float(v) for v in text[1:-1].split(",")), key
        elif plain and text != "none" and re.fullmatch(r"[-+0-9.e]+", text):
            assert value == float(text) and not isinstance(value, bool), key
        elif plain and text != "none":
            assert value == text, key
        elif key == "unload_at":
            assert value == (), key
        else:   # computed per test ("by `rate_rule`", "0.01 (agglomerate 0.1)") or none
            assert value is None, key
    assert isinstance(settings.samples, int) and isinstance(settings.max_steps, int)


def test_the_lattice_specimen_of_a_spec(tmp_path):
    specimen, settings, text = load_spec(write(tmp_path, LATTICE + MATERIALS
                                               + "[test]\nstrain_rate = 3.5\n"
                                               + 'rate_rule = "wave"\n'))
    assert "strain_rate = 3.5" in text and settings.strain_rate == 3.5
    assert settings.rate_rule == "wave"
    assert specimen.position.shape == (24, 3) and specimen.lattice
    # bonds to the six neighbours: (nx-1) ny nz + nx (ny-1) nz + nx ny (nz-1)
    assert specimen.bonds.shape == (2 * 2 * 4 + 3 * 1 * 4 + 3 * 2 * 3, 2)
    assert np.all(specimen.bond_diameter == pytest.approx(0.4 * 2e-3, rel=1e-12))
    assert specimen.bond_materials[0].young_modulus == 2e8
    assert specimen.materials[0].young_modulus == 1e8
    assert specimen.shape == "box" and specimen.contact_model == "hertz_mindlin"
    specimen, _, _ = load_spec(write(tmp_path, LATTICE + 'shape = "cylinder"\n'
                                     'contact_model = "linear"\n' + MATERIALS))
    assert specimen.shape == "cylinder" and specimen.contact_model == "linear"
    # a spec override (``bondem lab --set``)
    specimen, settings, _ = load_spec(write(tmp_path, LATTICE + MATERIALS),
                                      {"specimen.radius": 2e-3, "test.samples": 77})
    assert specimen.radius == pytest.approx(np.full(24, 2e-3)) and settings.samples == 77


def test_the_settings_a_spec_sets(tmp_path):
    spec = write(tmp_path, LATTICE + MATERIALS + "[test]\ngauge = [0, 0.2]\n"
                 "unload_at = [0.001, 0.004]\nconfining_stress = 2e6\n"
                 "[test.platen_material]\ndensity = 7800.0\nyoung_modulus = 2e11\n"
                 "friction = 0.1\n")
    _, settings, _ = load_spec(spec)
    assert settings.gauge == (0.0, 0.2) and settings.unload_at == (0.001, 0.004)
    assert settings.confining_stress == 2e6
    assert settings.platen_material.young_modulus == 2e11
    assert settings.platen_material.friction == 0.1


def test_each_generated_specimen_key_reaches_the_generator(tmp_path, monkeypatch):
    seen = {}

    def fake(shape, size, **kwargs):
        seen.update(kwargs, shape=shape, size=size)
        return "made"
    monkeypatch.setattr(spec_module, "make_specimen", fake)
    text = ('[specimen]\nshape = "cylinder"\nsize = [0.008, 0.016]\nparticle_radius = 4e-4\n'
            "solids_fraction = 0.6\nseed = 7\nmax_gap = 5e-5\ndiameter_ratio = 0.3\n"
            'max_per_particle = 9\nconsolidation_stress = 1e5\ncontact_model = "linear"\n'
            + MATERIALS)
    specimen, _, _ = load_spec(write(tmp_path, text))
    assert specimen == "made"
    assert seen.pop("material").young_modulus == 1e8
    assert seen.pop("bond_material").young_modulus == 2e8
    assert seen == {"shape": "cylinder", "size": [0.008, 0.016], "particle_radius": 4e-4,
                    "radius_distribution": None, "solids_fraction": 0.6, "seed": 7,
                    "max_gap": 5e-5, "diameter_ratio": 0.3, "max_per_particle": 9,
                    "consolidation_stress": 1e5, "contact_model": "linear"}
    # an adhesive contact model needs no bond material
    seen.clear()
    text = ('[specimen]\nshape = "sphere"\nsize = [0.004]\n'
            'radius_distribution = {radius = [2e-4, 3e-4], fraction = [0.5, 0.5]}\n'
            'contact_model = "jkr"\n[specimen.material]\ndensity = 2500.0\n'
            "young_modulus = 1e8\n")
    load_spec(write(tmp_path, text))
    assert seen["bond_material"] is None and seen["particle_radius"] is None
    assert seen["radius_distribution"] == {"radius": [2e-4, 3e-4], "fraction": [0.5, 0.5]}
    assert (seen["solids_fraction"], seen["seed"], seen["max_gap"]) == (0.55, 0, 0.0)


def test_a_generated_specimen_and_a_scene_specimen(tmp_path):
    text = ('[specimen]\nshape = "box"\nsize = [0.004, 0.005, 0.006]\n'
            "particle_radius = 5e-4\nsolids_fraction = 0.4\nseed = 3\nmax_gap = 1e-4\n"
            + MATERIALS)
    specimen, _, _ = load_spec(write(tmp_path, text))
    extent = specimen.position.max(axis=0) - specimen.position.min(axis=0)
    assert np.all(extent < [0.004, 0.005, 0.006]) and np.all(extent > [0.002, 0.003, 0.004])
    assert specimen.bonds.shape[0] > specimen.position.shape[0]
    again, _, _ = load_spec(write(tmp_path, text.replace("seed = 3", "seed = 4")))
    assert not np.array_equal(again.position[:5], specimen.position[:5])
    write(tmp_path, "x,y,z,radius,material\n0,0,0,1e-3,glass\n2e-3,0,0,1e-3,glass\n",
          "particles.csv")
    write(tmp_path, "[simulation]\nend_time = 1e-3\n[materials.glass]\ndensity = 2500.0\n"
          "young_modulus = 1e8\n[bond_materials.b]\nyoung_modulus = 1e8\n"
          '[particles]\nfile = "particles.csv"\n[bonds]\nmax_gap = 1e-5\n'
          'material = "b"\ndiameter_ratio = 0.5\n', "scene.toml")
    specimen, _, _ = load_spec(write(tmp_path, '[specimen]\nscene = "scene.toml"\n'
                                     'shape = "cylinder"\n'))
    assert specimen.position.shape == (2, 3) and specimen.bonds.shape == (1, 2)
    assert specimen.shape == "cylinder"
    specimen, _, _ = load_spec(write(tmp_path, '[specimen]\nscene = "scene.toml"\n'))
    assert specimen.shape == "box"


BAD = [
    (LATTICE + MATERIALS + "[other]\n", "other",
     "unknown key 'other'; allowed: specimen, test"),
    ("specimen = 3\n", "specimen", "expected a table"),
    ("test = 3\n" + LATTICE + MATERIALS, "test", "expected a table"),
    ("[test]\nsamples = 3\n", "specimen", "missing required table"),
    ('[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\nsize = [1, 1, 1]\n' + MATERIALS,
     "specimen.size", "size applies to generated specimens (shape), not to a lattice"),
    ('[specimen]\nlattice = [2, 2, 2]\nscene = "x.toml"\nradius = 1e-3\n',
     "specimen.shape", "give exactly one of shape (a generated specimen), lattice "
     "[nx, ny, nz] or scene (a scene file)"),
    ("[specimen]\nradius = 1e-3\n", "specimen.shape", "give exactly one of shape (a "
     "generated specimen), lattice [nx, ny, nz] or scene (a scene file)"),
    ('[specimen]\nscene = "missing.toml"\n', "specimen.scene",
     "value 'missing.toml': no such file"),
    ("[specimen]\nlattice = [2, 2, 2]\n" + MATERIALS, "specimen.radius",
     "a lattice needs radius (m)"),
    ('[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\nshape = "disc"\n' + MATERIALS,
     "specimen.shape", "value 'disc': a lattice is a box or a cylinder"),
    ("[specimen]\nlattice = [2, 2.5, 2]\nradius = 1e-3\n" + MATERIALS, "specimen.lattice",
     "value [2, 2.5, 2]: expected 3 integers >= 1"),
    ("[specimen]\nlattice = [2, 0, 2]\nradius = 1e-3\n" + MATERIALS, "specimen.lattice",
     "value [2, 0, 2]: expected 3 integers >= 1"),
    ("[specimen]\nlattice = [2, 2]\nradius = 1e-3\n" + MATERIALS, "specimen.lattice",
     "value [2, 2]: expected 3 integers >= 1"),
    ('[specimen]\nshape = "box"\nparticle_radius = 1e-3\n' + MATERIALS, "specimen.size",
     "missing required key"),
    ('[specimen]\nshape = "cylinder"\nsize = [1e-2, 2e-2, 1e-2]\nparticle_radius = 1e-3\n'
     + MATERIALS, "specimen.size", "value [0.01, 0.02, 0.01]: expected 2 numbers > 0"),
    ('[specimen]\nshape = "sphere"\nsize = [true]\nparticle_radius = 1e-3\n' + MATERIALS,
     "specimen.size", "value [True]: expected 1 number > 0"),
    ('[specimen]\nshape = "sphere"\nsize = [inf]\nparticle_radius = 1e-3\n' + MATERIALS,
     "specimen.size", "value [inf]: expected 1 number > 0"),
    ('[specimen]\nshape = "sphere"\nsize = 0.01\nparticle_radius = 1e-3\n' + MATERIALS,
     "specimen.size", "value 0.01: expected 1 number > 0"),
    ('[specimen]\nshape = "sphere"\nsize = [1e-2]\n' + MATERIALS, "specimen.particle_radius",
     "give exactly one of particle_radius (m) or radius_distribution"),
    ('[specimen]\nshape = "sphere"\nsize = [1e-2]\nparticle_radius = 1e-3\n'
     "radius_distribution = {radius = [1e-3], fraction = [1.0]}\n" + MATERIALS,
     "specimen.particle_radius",
     "give exactly one of particle_radius (m) or radius_distribution"),
    ('[specimen]\nshape = "sphere"\nsize = [1e-3]\nparticle_radius = 1e-2\n' + MATERIALS,
     "specimen", "cannot make the specimen: the particles do not fit inside the volume "
     "(particle radius too large for the container?)"),
    ("[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\n", "specimen.material",
     "missing required table"),
    ("[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\n[specimen.material]\ndensity = 1.0\n"
     "young_modulus = 1e8\n", "specimen.bond_material", "missing required table"),
    ("[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\n[specimen.material]\ndensity = 1.0\n"
     "young_modulus = 1e8\n[specimen.bond_material]\nyoung_modulus = 1e8\n"
     'model = "kelvin"\nyield_strength = 1e6\n', "specimen.bond_material",
     "bond material 'bond': yield_strength = 1000000.0 needs model = 'concrete' or "
     "'creep' or 'elastic_plastic' or 'weakening' (model = 'kelvin' has no such "
     "parameter)"),
    ("[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\nmaterial = 3\n"
     "[specimen.bond_material]\nyoung_modulus = 1e8\n", "specimen.material",
     "value 3: expected a table"),
    ("[specimen]\nlattice = [2, 2, 2]\nradius = 1e-3\ncolour = 1\n" + MATERIALS,
     "specimen.colour", "unknown key 'colour'; allowed: shape, lattice, scene, size, "
     "particle_radius, radius, radius_distribution, solids_fraction, seed, max_gap, "
     "diameter_ratio, max_per_particle, consolidation_stress, contact_model, material, "
     "bond_material"),
    (LATTICE + MATERIALS + "[test]\ngauge = [0.1]\n", "test.gauge",
     "value [0.1]: expected 2 numbers >= 0"),
    (LATTICE + MATERIALS + "[test]\ngauge = [-0.1, 0.2]\n", "test.gauge",
     "value [-0.1, 0.2]: expected 2 numbers >= 0"),
    (LATTICE + MATERIALS + '[test]\nrate_rule = "auto"\n', "test.rate_rule",
     "value 'auto'; allowed: 'bonds', 'wave'"),
    (LATTICE + MATERIALS + '[test]\nunload_at = "soon"\n', "test.unload_at",
     "value 'soon': expected a list of platen strains in (0, 1)"),
    (LATTICE + MATERIALS + "[test]\nunload_at = [0.001, -0.002]\n", "test.unload_at",
     "value [0.001, -0.002]: expected 2 numbers > 0"),
    (LATTICE + MATERIALS + "[test]\nunload_at = true\n", "test.unload_at",
     "value True: expected a list of platen strains in (0, 1)"),
    (LATTICE + MATERIALS + "[test]\nunload_at = 3\n", "test.unload_at",
     "unload_at = [3.0]; platen strains in (0, 1)"),
    (LATTICE + MATERIALS + "[test]\ngrip = 0.6\n", "test.grip",
     "value 0.6 is outside the allowed range (0.0, 0.5)"),
    (LATTICE + MATERIALS + "[test]\nunload_to = 1.0\n", "test.unload_to",
     "value 1.0 is outside the allowed range [0.0, 1.0)"),
    (LATTICE + MATERIALS + "[test]\nunload_at = [0.001]\nunload_to = 0.0\n"
     "platen_material = {density = 1.0}\n", "test.platen_material.young_modulus",
     "missing required key"),
    (LATTICE + MATERIALS + "[test]\ngauge = [0.3, 0.2]\n", "test.gauge",
     "gauge = (0.3, 0.2); expected 0 <= low < high <= 0.5"),
]


@pytest.mark.parametrize("text, key, message", BAD)
def test_a_bad_spec_names_the_file_and_the_key(tmp_path, text, key, message):
    path = write(tmp_path, text)
    with pytest.raises(InputError) as error:
        load_spec(path)
    assert error.value.key == key
    assert str(error.value) == f"{path}: {key}: {message}"


def test_an_unreadable_spec_and_a_lattice_box(tmp_path):
    with pytest.raises(InputError) as error:
        load_spec(tmp_path)
    assert str(error.value).startswith(f"{tmp_path}: cannot read the lab spec (")
    specimen, _, _ = load_spec(write(tmp_path, LATTICE + 'shape = "box"\n' + MATERIALS))
    assert specimen.shape == "box" and specimen.position.shape == (24, 3)


def test_one_unloading_strain_may_be_given_as_a_number(tmp_path):
    _, settings, _ = load_spec(write(tmp_path, LATTICE + MATERIALS
                                     + "[test]\nunload_at = 0.002\n"))
    assert settings.unload_at == (0.002,) and isinstance(settings.unload_at[0], float)

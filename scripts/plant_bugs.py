"""Planted-bug audit of the Numba-compiled physics and loop bodies (mutmut cannot mutate
them): each entry below is one plausible bug, planted by replacing a line of the source,
the named tests run, the source restored. A bug that no test catches is a survivor.

    python scripts/plant_bugs.py [--only SUBSTRING] [--markdown]

Run from the repository root with bondem installed in editable mode (the tests import the
edited source). Prints one row per bug: caught or SURVIVED, and the seconds it took;
--markdown prints the table docs/testing.md keeps. Exit status 1 when a bug survived.
"""
import argparse
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SRC = ROOT / "src" / "bondem"

# (file under src/bondem, text to replace, replacement, tests, what the bug is)
BUGS = [
    ("physics/bond_plastic.py", "    stress = (strain - plastic_strain) * young_modulus",
     "    stress = strain * young_modulus", ["tests/test_bond_plastic.py"],
     "elastic-plastic: yield tested on the total strain (plastic strain not carried)"),
    ("physics/bond_plastic.py", "        return limit, strain - limit / young_modulus, limit",
     "        return limit, strain + limit / young_modulus, limit",
     ["tests/test_bond_plastic.py"],
     "elastic-plastic: plastic offset after tensile yield with the wrong sign"),
    ("physics/bond_plastic.py", "    if stress < 0.0:\n        limit = yield_strength * ratio",
     "    if stress > 0.0:\n        limit = yield_strength * ratio",
     ["tests/test_bond_plastic.py"],
     "elastic-plastic: compressive yield ratio applied in tension"),
    ("physics/bond_plastic.py", "            if compat:\n                cap = limit * area",
     "            if True:\n                cap = limit * area",
     ["tests/test_bond_plastic.py", "tests/test_validate.py::"
      "test_real_musen_plastic_runs_pass_in_compat_mode_and_are_info_in_spec_mode"],
     "elastic-plastic: MUSEN's tangential cap (compressive yield) in bondem's own law"),
    ("physics/bond_plastic.py", "    stretch = length - l0 - plastic_strain * l0",
     "    stretch = length - l0", ["tests/test_bond_plastic.py"],
     "elastic-plastic: stored energy measured from L0, not the plastic length"),
    ("physics/bond_creep.py", "    creep = dt * rate * math.pow(abs(stress), exponent)",
     "    creep = dt * rate * abs(stress)", ["tests/test_bond_creep.py"],
     "creep: the exponent m ignored (linear creep)"),
    ("physics/bond_creep.py", "    if stress > 0.0:\n        strain_p += creep",
     "    if stress > 0.0:\n        strain_p -= creep", ["tests/test_bond_creep.py"],
     "creep: tensile creep shortens the bond"),
    ("physics/bond_creep.py",
     "dt * rate * math.pow(size / area, exponent) * shear_modulus * area / size",
     "dt * rate * math.pow(size / area, exponent) * shear_modulus / size",
     ["tests/test_bond_creep.py"],
     "creep: tangential creep rate without the bond's area"),
    ("physics/bond_parallel.py",
     "    limit = cohesion - normal * math.tan(",
     "    limit = cohesion + normal * math.tan(", ["tests/test_bond_parallel.py"],
     "parallel: Mohr-Coulomb strength falling with compression"),
    ("physics/bond_parallel.py",
     "    bending = beta * norm(m_t) * radius / second",
     "    bending = norm(m_t) * radius / second", ["tests/test_bond_parallel.py"],
     "parallel: moment contribution factor ignored in the tension test"),
    ("physics/bond_parallel.py",
     "                lost = 0.5 * kn * (length - l0) * (length - l0) * (grown - damage)",
     "                lost = 0.5 * kn * (length - l0) * (length - l0) * grown",
     ["tests/test_bond_parallel.py"],
     "parallel: softening books the whole damage each step, not its growth"),
    ("physics/bond_parallel.py",
     "    eps_f = eps_0 * (1.0 + 1.0 / softening)",
     "    eps_f = eps_0 * (1.0 + softening)", ["tests/test_bond_parallel.py"],
     "parallel: softening strain range inverted"),
    ("physics/bond_weakening.py",
     "        dropped = stress * factor * counter_uniform(seed, b, count)\n        count += 1",
     "        dropped = stress * factor * counter_uniform(seed, b, count)",
     ["tests/test_bond_weakening.py"],
     "weakening: the draw counter not advanced after a normal drop"),
    ("physics/bond_weakening.py",
     "        lost = 0.5 * (stress * stress - dropped * dropped) / young * area * l0",
     "        lost = 0.5 * (stress - dropped) ** 2 / young * area * l0",
     ["tests/test_bond_weakening.py"],
     "weakening: released energy from the stress difference, not the stored energies"),
    ("physics/bond_aerogel.py", "        if strain < carried:\n            carried = strain",
     "        if strain > carried:\n            carried = strain",
     ["tests/test_bond_aerogel.py"],
     "aerogel: a crushed bond tracks its largest, not its smallest, strain"),
    ("physics/bond_aerogel.py",
     "    work = 0.5 * (old_force + force) * stiffness * (length - lp)",
     "    work = force * stiffness * (length - lp)", ["tests/test_bond_aerogel.py"],
     "aerogel: the step's work from the new force only (not trapezoidal)"),
    ("physics/bond_concrete.py",
     "            plastic_strain += (stress - limit) * (1.0 + alpha) / young",
     "            plastic_strain += (stress - limit) * (1.0 - alpha) / young",
     ["tests/test_bond_concrete.py", "tests/test_validate.py::"
      "test_real_musen_plastic_runs_pass_in_compat_mode_and_are_info_in_spec_mode"],
     "concrete: tensile softening update with (1 - alpha) instead of (1 + alpha)"),
    ("physics/bond_concrete.py",
     "        limit = -yield_strength + plastic_strain * young * beta",
     "        limit = -yield_strength - plastic_strain * young * beta",
     ["tests/test_bond_concrete.py"],
     "concrete: compression softens instead of hardening"),
    ("physics/bond_concrete.py",
     "bond_loads_on_particles(r, f_n, scale(f_t, l0),",
     "bond_loads_on_particles(r, f_n, f_t,",
     ["tests/test_validate.py::"
      "test_real_musen_plastic_runs_pass_in_compat_mode_and_are_info_in_spec_mode"],
     "concrete: MUSEN's tangential force (overlap times G A) not reproduced"),
    ("backends/loops.py", "        materials.tangential_strength[m] * scatter, materials.breakage[m],",
     "        materials.tangential_strength[m], materials.breakage[m],",
     ["tests/test_strength_scatter.py", "tests/test_bond_parallel.py"],
     "scatter: tangential strength not scattered (scalar path)"),
    ("backends/loops.py", "        materials.poisson_ratio[m], diameter, materials.normal_strength[m] * scatter,",
     "        materials.poisson_ratio[m], diameter, materials.normal_strength[m],",
     ["tests/test_strength_scatter.py"],
     "scatter: normal strength not scattered (scalar path)"),
    ("backends/cpu.py", "            s[_NORMAL_STRENGTH * B + q] = normal_strength[m] * strength[b]",
     "            s[_NORMAL_STRENGTH * B + q] = normal_strength[m]",
     ["tests/test_strength_scatter.py"],
     "scatter: normal strength not scattered (vectorised path)"),
    ("backends/loops.py", '"columns[b, 1] = s1", "columns[b, 2] = s2"',
     '"columns[b, 1] = s2", "columns[b, 2] = s1"',
     ["tests/test_bond_plastic.py"],
     "SPRINGS: a model's two state columns swapped when stored"),
    ("backends/loops.py", '"columns[b, 0] += lost"', '"columns[b, 0] = lost"',
     ["tests/test_bond_plastic.py"],
     "SPRINGS: the dissipated energy overwritten instead of summed"),
    ("model.py", "draws = rng.weibull(spread, self.n_bonds) / math.gamma(1.0 + 1.0 / spread)",
     "draws = rng.weibull(spread, self.n_bonds)", ["tests/test_strength_scatter.py"],
     "scatter: Weibull factors without the mean-1 scale"),
    ("physics/bond_kelvin.py", "    c_t = viscosity * shear_stiffness",
     "    c_t = viscosity * normal_stiffness", ["tests/test_bond_kelvin.py",
                                              "tests/test_closed_forms.py"],
     "Kelvin: the tangential dashpot built on the normal spring"),
    ("physics/contact_jkr.py",
     "    return 4.0 * e_star * a * a * a / (3.0 * r_star) - math.sqrt(8.0 * math.pi * w * e_star",
     "    return 4.0 * e_star * a * a * a / (3.0 * r_star) - math.sqrt(4.0 * math.pi * w * e_star",
     ["tests/test_contacts_adhesive.py"], "JKR: adhesive term of the surface energy w/2"),
    ("physics/contact_jkr.py", "    load = f_n + 3.0 * math.pi * w * r_star",
     "    load = f_n", ["tests/test_contacts_adhesive.py"],
     "JKR: Coulomb limit without twice the pull-off force"),
    ("physics/contact_jkr.py",
     "    return jkr_integral(a, r_star, e_star, k) - jkr_integral(a_c, r_star, e_star, k)",
     "    return jkr_integral(a, r_star, e_star, k)",
     ["tests/test_contacts_adhesive.py"], "JKR: potential not zero at the pull-off point"),
    ("physics/contact_jkr.py", "HYSTERETIC = True", "HYSTERETIC = False",
     ["tests/test_contacts_adhesive.py"], "JKR: attraction before the surfaces touch"),
    ("physics/contact_vdw.py", "    return hamaker * r_star / (6.0 * h * h)",
     "    return hamaker * r_star / (6.0 * h)", ["tests/test_contacts_adhesive.py"],
     "van der Waals: force falling as 1/h"),
    ("physics/contact_vdw.py", "        return scale(n, pull), (0.0, 0.0, 0.0)",
     "        return scale(n, -pull), (0.0, 0.0, 0.0)", ["tests/test_contacts_adhesive.py"],
     "van der Waals: repulsive beyond contact"),
    ("physics/contact_liquid.py",
     "    return (1.0 + 0.5 * (pair[q, ANGLE] * math.pi / 180.0)) * volume ** (1.0 / 3.0)",
     "    return (1.0 + (pair[q, ANGLE] * math.pi / 180.0)) * volume ** (1.0 / 3.0)",
     ["tests/test_contacts_adhesive.py"], "liquid bridge: rupture at (1 + theta) V^(1/3)"),
    ("physics/contact_liquid.py",
     "    f_visc = -6.0 * math.pi * viscosity * r_star * r_star * v_n / film",
     "    f_visc = -6.0 * math.pi * viscosity * r_star * v_n / film",
     ["tests/test_contacts_adhesive.py"], "liquid bridge: Reynolds force with R*, not R*^2"),
    ("physics/contact_popov.py", "    return (f_a * (-1.0 + 0.12 * x ** (5.0 / 3.0)),",
     "    return (f_a * (-1.0 + 0.12 * x ** (3.0 / 2.0)),", ["tests/test_contacts_adhesive.py"],
     "Popov's JKR: exponent 3/2 for 5/3"),
    ("physics/contact_hertz_musen.py",
     "                      - math.sqrt(8.0 * math.pi * e_star * adhesion * a3))",
     "                      - math.sqrt(4.0 * math.pi * e_star * adhesion * a3))",
     ["tests/test_musen_contacts.py::test_real_musen_contact_runs_are_reproduced_to_round_off"],
     "MUSEN's JKR: the adhesive term of half the surface energy"),
    ("physics/contact_hertz_musen.py",
     "        if norm(scale(overlap_t, -k_t)) > friction * abs(f_n + damping):\n            xi = cut",
     "        if norm(scale(overlap_t, -k_t)) > friction * abs(f_n + damping):\n            xi = xi",
     ["tests/test_musen_contacts.py::test_real_musen_contact_runs_are_reproduced_to_round_off"],
     "MUSEN's Popov wall model: a sliding spring not cut to the Coulomb force"),
    ("contacts.py", "    if not reach_of or radius_max <= 0.0:",
     "    if True or not reach_of or radius_max <= 0.0:", ["tests/test_contacts_adhesive.py"],
     "neighbour lists without the laws' reach (necks lost beyond the skin)"),
    ("backends/loops.py", "    apart = overlap <= -reach or distance == 0.0",
     "    apart = overlap <= 0.0 or distance == 0.0", ["tests/test_contacts_adhesive.py"],
     "pair kernel ignores the reach beyond contact"),
    ("backends/loops.py", "    return (rows.energy[c] != 0.0 or rows.force[c, 0] != 0.0",
     "    return (rows.energy[c] != 0.0 and rows.force[c, 0] != 0.0",
     ["tests/test_contacts_adhesive.py"],
     "a formed contact row taken for reset unless both its energy and x force are set"),
]


def plant(entry):
    """Plant one bug, run its tests, restore: (caught, seconds)."""
    name, old, new, tests, _ = entry
    path = SRC / name
    original = path.read_text()
    if original.count(old) != 1:
        raise SystemExit(f"{name}: the text to replace occurs {original.count(old)} times: "
                         f"{old!r}")
    start = time.perf_counter()
    try:
        path.write_text(original.replace(old, new))
        done = subprocess.run([sys.executable, "-m", "pytest", "-x", "-q", "-o", "addopts=",
                               "-p", "no:cacheprovider", *tests], cwd=ROOT,
                              capture_output=True, text=True, timeout=1800)
    finally:
        path.write_text(original)
    return done.returncode != 0, time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", default="", help="run the bugs whose text contains this")
    parser.add_argument("--markdown", action="store_true", help="print the docs table")
    args = parser.parse_args()
    rows = []
    for entry in BUGS:
        if args.only not in entry[4]:
            continue
        caught, seconds = plant(entry)
        rows.append((entry, caught))
        print(f"{'caught  ' if caught else 'SURVIVED'} {seconds:6.0f} s  {entry[4]}",
              flush=True)
    if args.markdown:
        print("\n| bug planted | file | tests | result |\n|---|---|---|---|")
        for (name, _, _, tests, what), caught in rows:
            short = ", ".join(t.split("::")[0].replace("tests/", "") for t in tests)
            print(f"| {what} | {name} | {short} | {'caught' if caught else 'survived'} |")
    return 0 if all(caught for _, caught in rows) else 1


if __name__ == "__main__":
    sys.exit(main())

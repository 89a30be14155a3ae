"""Weakening bond: the elastic bond whose stress, each time it passes the yield stress, drops
to a random fraction of itself; MUSEN's ModelSBWeakening ("Bond with weakening", MUSEN
1.74.2), with its C rand() replaced by a seeded counter-based draw per bond.

Parameters: the yield stress sigma_y (yield_strength; MUSEN's bond material property
YIELD_STRENGTH), the weakening factor w (weakening_factor; WEAKENING_FACTOR), the fracture
strains (fracture_strain: MUSEN's BREAKAGE_STRAIN eps_b; compressive_fracture_strain: MUSEN
breaks at -2 eps_b with COMPRESSIVE_BREAK 1) and strength_seed. With eps = (L - L0)/L0 and
the plastic strain eps_p (column 1), each step:
    sigma = E (eps - eps_p)
    |sigma| > sigma_y:  sigma <- w u sigma,  eps_p = eps - sigma / E      (u uniform [0, 1))
    F_n = sigma A n
    |F_t| / A > sigma_y:  F_t <- w u' F_t                                  (u' a second draw)
The moments are the elastic bond's. With w = 0 every yield drops the stress to zero: a
bond pulled at a steady rate has a sawtooth force, 0 to sigma_y A, one tooth per
sigma_y L0 / E of stretch. Draw k of bond b is hash(strength_seed, b, k) (a 32-bit integer
hash, the same in Python, on the CPU and on the GPU); column 2 counts the draws, so a run
draws the same numbers on 1 or 2 threads, on the GPU and after a resume. Breakage: eps >
eps_f or eps < -eps_fc, and bondem's stress criterion on the strengths (inf by default).
Booked: the stored energy each drop releases (column 0).

MUSEN-compatible runs (musen_compat) use MUSEN's springs and break by the strains only;
MUSEN's own draws (C rand(), seeded nowhere) cannot be reproduced: with w = 0 the draws
do not matter and a real MUSEN run is followed to round-off (docs/bond_weakening.md).
"""
import math

from ._registry import physics
from .bond_elastic import INTACT
from .bond_plastic import PARAMETERS as PLASTIC, fracture_mode, plastic_normal_energy, \
    strength_mode  # noqa: F401  (plastic_normal_energy: the ENERGY it shares)
from .vector import dot, norm, scale

NAME = "weakening"
PARAMETERS = {key: PLASTIC[key] for key in ("yield_strength", "fracture_strain",
                                            "compressive_fracture_strain")}
PARAMETERS["weakening_factor"] = ("number", 0.5, 0.0, 1.0, True, True)
UNITS = {"yield_strength": "Pa", "fracture_strain": "-", "compressive_fracture_strain": "-",
         "weakening_factor": "-"}
LOADS = None
SPRINGS = "weakening_springs"
COLUMNS = ("normal plastic strain (-)", "draws made (-)")
ENERGY = "plastic_normal_energy"
STATE = ("J released by the bond's weakening", "dissipated_weakening")
VECTORISED = False


def _import(words, entry):
    """MUSEN's CONSIDER_BREAKAGE, BREAKAGE_STRAIN and COMPRESSIVE_BREAK as bondem keys."""
    strain = words.get("BREAKAGE_STRAIN", 0.1)
    breaks = bool(words.get("CONSIDER_BREAKAGE", 1.0))
    entry["fracture_strain"] = strain if breaks else float("inf")
    entry["compressive_fracture_strain"] = (2.0 * strain if breaks and
                                            words.get("COMPRESSIVE_BREAK", 0.0)
                                            else float("inf"))
    entry["weakening_factor"] = words.get("WEAKENING_FACTOR", 0.5)


def _export(values):
    """MODEL_SB_PARAMS of a weakening bond material (dict of its keys) and a note when
    MUSEN cannot express it (its compressive fracture is twice the tensile one)."""
    tensile = float(values.get("fracture_strain", 0.1))
    compressive = float(values.get("compressive_fracture_strain", float("inf")))
    note = None
    if math.isfinite(compressive) and compressive != 2.0 * tensile:
        note = ("weakening bond: MUSEN breaks in compression at twice the tensile fracture "
                f"strain ({2 * tensile:g}), not at compressive_fracture_strain "
                f"{compressive:g}")
    words = (f"CONSIDER_BREAKAGE {int(math.isfinite(tensile))} "
             f"COMPRESSIVE_BREAK {int(math.isfinite(compressive))} "
             f"BREAKAGE_STRAIN {tensile if math.isfinite(tensile) else 0.1!r} "
             f"WEAKENING_FACTOR {float(values.get('weakening_factor', 0.5))!r}")
    return words, note


# MUSEN's counterpart (io/musen_text.py): its parameters need the two conversions above
MUSEN = {"model": "ModelSBWeakening", "parameters": {}, "properties": {15: "yield_strength"},
         "strengths": False, "import": _import, "export": _export}


def time_scales(model, bonds, reduced_mass, musen_compat=False):
    """No limit beyond the elastic springs': {}."""
    return {}


@physics
def hash32(x):
    """A 32-bit integer hash of 0 <= x < 2^32 (integer products stay below 2^59, so Python,
    Numba's int64 and CUDA agree bit for bit)."""
    x = (((x >> 16) ^ x) * 0x45D9F3B) & 0xFFFFFFFF
    x = (((x >> 16) ^ x) * 0x45D9F3B) & 0xFFFFFFFF
    return (x >> 16) ^ x


@physics
def counter_uniform(seed, b, k):
    """Draw k of bond b under ``seed``, uniform in [0, 1): a hash of the three counters,
    no state but k."""
    x = hash32(hash32(hash32(seed & 0xFFFFFFFF) ^ (b & 0xFFFFFFFF)) ^ (k & 0xFFFFFFFF))
    return x / 4294967296.0


@physics
def weakening_springs(musen, b, time, dt, length, l0, diameter, n, f_n, f_t, m_n, m_t, mode,
                      kn, kt, scatter, lp, plastic_strain, draws, materials, m):
    """SPRINGS of the weakening bond (module docstring): (F_n, F_t in N, M_n, M_t in N m,
    break mode, plastic strain, draws made, J released by this step's drops)."""
    compat = False
    if musen is not None:
        compat = musen
    radius = 0.5 * diameter
    area = math.pi * radius * radius
    young = materials.young_modulus[m]
    yield_strength = materials.yield_strength[m] * scatter
    factor = materials.weakening_factor[m]
    seed = int(materials.strength_seed[m])
    count = int(draws)
    strain = (length - l0) / l0
    stress = (strain - plastic_strain) * young
    lost = 0.0
    if abs(stress) > yield_strength:
        dropped = stress * factor * counter_uniform(seed, b, count)
        count += 1
        plastic_strain = strain - dropped / young
        lost = 0.5 * (stress * stress - dropped * dropped) / young * area * l0
        stress = (strain - plastic_strain) * young
    if compat:
        f_n = scale(scale(n, stress), area)
    else:
        f_n = scale(n, stress * area)
    size = norm(f_t)
    if size > yield_strength * area:
        f_t_new = scale(f_t, factor * counter_uniform(seed, b, count))
        count += 1
        lost += 0.5 * (size * size - dot(f_t_new, f_t_new)) / kt
        f_t = f_t_new
    mode = fracture_mode(strain, materials, m)
    if mode == INTACT:
        mode = strength_mode(compat, length, l0, f_n, f_t, m_n, m_t, diameter, scatter,
                             materials, m)
    return f_n, f_t, m_n, m_t, mode, plastic_strain, float(count), lost

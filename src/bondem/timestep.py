"""Stable time step of a model (SPEC section 1)."""
import numpy as np

from .physics import field_models


def step_count(end_time, time_step):
    """Steps of a run to ``end_time`` (s) with ``time_step`` (s): the nearest whole number,
    so an end time a rounding error off a whole number of steps takes that number. The
    runner, the LAMMPS deck and the MUSEN script all count with this."""
    return max(0, int(round(float(end_time) / float(time_step))))


def time_scales(model, musen_compat=False):
    """Smallest time scale (s) of each kind: {"rayleigh", "bond_axial", "bond_bending"},
    those of the bond models in use (e.g. "bond_dashpot" of Kelvin bonds) and of the
    field models that act (physics/field_models.py: "fluid_drag", m / (3 pi mu d), when a
    fluid drags the particles, "frame_rotation", 1 / |Omega|, in a rotating frame).

    Rayleigh: pi r sqrt(rho / G) / (0.1631 nu + 0.8766) per particle. Bonds:
    sqrt(m_red L0 / (E A_b)) and sqrt(I_red L0 / (E I)), with the pair's reduced mass
    and reduced moment of inertia. musen_compat: passed to the bond models (MUSEN's Kelvin
    viscosity is no time, for one).
    """
    table = model.material_table()
    density = table["density"][model.material]
    young = table["young_modulus"][model.material]
    poisson = table["poisson_ratio"][model.material]
    shear_modulus = young / (2.0 * (1.0 + poisson))
    rayleigh = np.pi * model.radius * np.sqrt(density / shear_modulus) / (0.1631 * poisson + 0.8766)
    scales = {"rayleigh": float(rayleigh.min()) if rayleigh.size else np.inf}
    if model.n_bonds:
        i, j = model.bond_pairs[:, 0], model.bond_pairs[:, 1]
        reduced_mass = model.mass[i] * model.mass[j] / (model.mass[i] + model.mass[j])
        reduced_inertia = (model.inertia[i] * model.inertia[j]
                           / (model.inertia[i] + model.inertia[j]))
        bond_young = model.bond_material_table()["young_modulus"][model.bond_material]
        radius = 0.5 * model.bond_diameter
        area = np.pi * radius ** 2
        second_moment = 0.25 * np.pi * radius ** 4
        length = model.bond_initial_length
        scales["bond_axial"] = float(np.sqrt(reduced_mass * length / (bond_young * area)).min())
        scales["bond_bending"] = float(
            np.sqrt(reduced_inertia * length / (bond_young * second_moment)).min())
        # and each bond model's own limits (time_scales in physics/bond_*.py)
        codes = model.bond_model_codes()
        for module in model.bond_models_used():
            bonds = np.flatnonzero(codes == module.CODE)
            scales.update(module.time_scales(model, bonds, reduced_mass[bonds], musen_compat))
    # each field model's own limits (time_scales in physics/field_*.py)
    scales.update(field_models.time_scales(model.fields, model.mass, model.radius))
    return scales


def stable_time_step(model, safety_factor=0.2, musen_compat=False):
    """(time step in s, limiting cause): safety_factor times the smallest time scale."""
    scales = time_scales(model, musen_compat)
    cause = min(scales, key=scales.get)
    return safety_factor * scales[cause], cause

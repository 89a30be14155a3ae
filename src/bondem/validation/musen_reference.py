"""A plain NumPy transcription of MUSEN's elastic-bond update (for comparison only).

MUSEN (github.com/msolids/musen), Models/SolidBonds/BondModelElastic/ModelSBElastic.cpp,
CModelSBElastic::CalculateSBForce: with left = i, right = j,
    currentBond = x_i - x_j            (GetSolidBond(x_right, x_left) = x_left - x_right)
    tempVector  = PrevBond x currentBond       (PrevBond = last step's currentBond, NOT unit)
    Phi         = c (c . (w_i + w_j)) dt / 2,  c = currentBond / |currentBond|
    M = (I + [tempVector]x)(I - [Phi]x)        (the 3x3 matrix written out in the source)
and every stored vector (tangential overlap, normal and tangential moments) is multiplied
by M before its increment is added; nothing is re-projected or re-normalised. See
docs/musen_compat.md for what differs from the SPEC's exact rotation T.
"""
import numpy as np


def skew(v):
    """Matrix [v]x with [v]x u = v x u."""
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def musen_rotation_matrix(previous_bond, current_bond, sum_angular_velocity, dt):
    """MUSEN's matrix M (dimensionless only when |bond| = 1 m: tempVector is in m^2).

    previous_bond, current_bond: x_i - x_j of the previous and current step (m);
    sum_angular_velocity: w_i + w_j (rad/s); dt: s.
    """
    temp = np.cross(previous_bond, current_bond)
    c = current_bond / np.linalg.norm(current_bond)
    phi = c * (np.dot(sum_angular_velocity, c) * dt * 0.5)
    # Written out exactly as in ModelSBElastic.cpp (row-major CMatrix3, M * v = rows . v).
    return np.array([
        [1 + temp[2] * phi[2] + temp[1] * phi[1], phi[2] - temp[2] - temp[1] * phi[0],
         -phi[1] - temp[2] * phi[0] + temp[1]],
        [temp[2] - phi[2] - temp[0] * phi[1], temp[2] * phi[2] + 1 + temp[0] * phi[0],
         -temp[2] * phi[1] + phi[0] - temp[0]],
        [-temp[1] - temp[0] * phi[2] + phi[1], -temp[1] * phi[2] + temp[0] - phi[0],
         temp[1] * phi[1] + temp[0] * phi[0] + 1]])


def musen_bond_step(xi, xj, vi, vj, wi, wj, previous_bond, overlap, normal_moment,
                    tangential_moment, initial_length, young, shear_modulus, area,
                    axial_moment, dt):
    """One MUSEN elastic-bond update. Returns (total force on i, normal moment,
    tangential moment, unsymmetric moment, tangential overlap, current bond), SI units.

    ``axial_moment`` is MUSEN's AxialMoment = I = pi R^4 / 4 (J = 2 I).
    """
    current = xi - xj
    length = np.linalg.norm(current)
    c = current / length
    w_sum = wi + wj
    relative_velocity = vi - vj - np.cross(w_sum, current * 0.5)
    rotation = musen_rotation_matrix(previous_bond, current, w_sum, dt)
    tangential_velocity = relative_velocity - c * np.dot(c, relative_velocity)
    w_rel = wi - wj
    w_n = c * np.dot(c, w_rel)
    w_t = w_rel - w_n
    strain = (length - initial_length) / initial_length
    normal_force = c * (-area * young * strain)
    overlap = rotation @ overlap - tangential_velocity * dt
    tangential_force = overlap * (shear_modulus * area / initial_length)
    normal_moment = rotation @ normal_moment - w_n * (
        dt * 2 * axial_moment * shear_modulus / initial_length)
    tangential_moment = rotation @ tangential_moment - w_t * (
        dt * young * axial_moment / initial_length)
    unsym = np.cross(current * 0.5, tangential_force)
    return (normal_force + tangential_force, normal_moment, tangential_moment, unsym,
            overlap, current)


def musen_breaks(strain, normal_force, overlap_force, normal_moment, tangential_moment,
                 diameter, axial_moment, area, normal_strength, tangential_strength,
                 criterion):
    """MUSEN 1547403's breakage test (CONSIDER_BREAKAGE = criterion: 0 none, 1, 2)."""
    if criterion == 0:
        return False
    force_length = np.linalg.norm(normal_force) * (1.0 if strain > 0 else -1.0)
    stress1 = force_length / area
    stress2 = np.linalg.norm(tangential_moment) * diameter / (2.0 * axial_moment)
    torque1 = np.linalg.norm(overlap_force) / area
    torque2 = np.linalg.norm(normal_moment) * diameter / (4.0 * axial_moment)
    if criterion == 1:
        return stress1 + stress2 >= normal_strength or torque1 + torque2 >= tangential_strength
    return (stress1 >= normal_strength or (stress2 >= normal_strength and strain > 0)
            or torque1 >= tangential_strength or torque2 >= tangential_strength)


def musen_run(model, state, dt, steps):
    """Run MUSEN's scheme in plain NumPy from ``state`` (not modified) for ``steps`` steps.

    The start-up ("prediction") force evaluation with bond increments of dt and a half
    kick without drift, then per step: bond forces (``musen_bond_step``, breakage by
    ``musen_breaks``; a bond that breaks applies nothing), v += (F + m g)/m dt,
    w += M/I dt, x += v dt (CPUSimulator.cpp). Bonds only: no contacts, damping, external
    loads or periodic boundaries. Returns a dict of arrays: position, velocity,
    angular_velocity (N,3), tangential_force, normal_moment, tangential_moment (B,3) on i,
    active (B,), break_time (B,) (NaN while intact). SI units.
    """
    if model.damping or np.any(model.periodic) or np.any(model.external_force) \
            or np.any(model.external_moment):
        raise ValueError("musen_run: bonds and gravity only (no damping, periodic "
                         "boundaries or external loads)")
    table = model.bond_material_table()
    x = state.position.copy()
    v = state.velocity.copy()
    w = state.angular_velocity.copy()
    n_bonds = model.n_bonds
    pairs = model.bond_pairs
    radius = 0.5 * model.bond_diameter
    area = np.pi * radius ** 2
    axial = 0.25 * np.pi * radius ** 4
    m_index = model.bond_material
    young = table["young_modulus"][m_index]
    shear = young / (2.0 * (1.0 + table["poisson_ratio"][m_index]))
    # bondem's criterion codes 0 none, 1 combined, 2 separate = MUSEN's CONSIDER_BREAKAGE.
    criterion = table["criterion"][m_index]
    previous = x[pairs[:, 0]] - x[pairs[:, 1]]
    # MUSEN's overlap times G A / L0 is its tangential force, bondem's F_t on i (same sign).
    overlap = state.bond_tangential_force / (shear * area / model.bond_initial_length)[:, None]
    normal_moment = state.bond_normal_moment.copy()
    tangential_moment = state.bond_tangential_moment.copy()
    active = state.bond_active.copy()
    break_time = state.bond_break_time.copy()
    time = state.time
    mass = model.mass[:, None]
    inertia = model.inertia[:, None]
    start_up = not state.started
    for k in range(steps + (1 if start_up else 0)):
        force = np.zeros_like(x)
        moment = np.zeros_like(x)
        for b in range(n_bonds):
            if not active[b]:
                continue
            i, j = pairs[b]
            total, mn, mt, unsym, ov, current = musen_bond_step(
                x[i], x[j], v[i], v[j], w[i], w[j], previous[b], overlap[b],
                normal_moment[b], tangential_moment[b], model.bond_initial_length[b],
                young[b], shear[b], area[b], axial[b], dt)
            overlap[b], normal_moment[b], tangential_moment[b], previous[b] = ov, mn, mt, \
                current
            length = np.linalg.norm(current)
            l0 = model.bond_initial_length[b]
            strain = (length - l0) / l0
            normal_force = current / length * (-area[b] * young[b] * strain)
            if musen_breaks(strain, normal_force, ov * (shear[b] * area[b] / l0), mn, mt,
                            model.bond_diameter[b], axial[b], area[b],
                            table["normal_strength"][m_index[b]],
                            table["tangential_strength"][m_index[b]], criterion[b]):
                active[b] = False
                break_time[b] = time
                continue
            force[i] += total
            force[j] -= total
            moment[i] += mn + mt - unsym
            moment[j] -= mn + mt + unsym
        force += model.mass[:, None] * model.gravity
        free = ~model.fixed
        kick = 0.5 * dt if (k == 0 and start_up) else dt
        v[free] += force[free] / mass[free] * kick
        w[free] += moment[free] / inertia[free] * kick
        if k == 0 and start_up:
            continue  # the prediction step moves nothing and takes no time
        x += v * dt
        time += dt
    shear_stiffness = (shear * area / model.bond_initial_length)[:, None]
    return dict(position=x, velocity=v, angular_velocity=w,
                tangential_force=overlap * shear_stiffness, normal_moment=normal_moment,
                tangential_moment=tangential_moment, active=active, break_time=break_time)

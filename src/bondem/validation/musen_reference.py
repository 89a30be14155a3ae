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

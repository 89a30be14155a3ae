"""Helpers for the contact tests: collision runs and the damped Hertz reference ODE."""
import math

import numpy as np
from scipy.integrate import solve_ivp

import bondem
from bondem.contacts import ContactSettings
from bondem.walls import MeshWall


def effective_modulus(material):
    """E* (Pa) of a pair of identical materials."""
    return material.young_modulus / (2.0 * (1.0 - material.poisson_ratio ** 2))


def damped_hertz_reference(e_star, r_star, m_star, restitution, speed):
    """(contact time s, restitution) of m* d'' = -4/3 E* sqrt(R*) d^1.5
    - 2 sqrt(5/6) |beta| sqrt(2 E* sqrt(R* d) m*) d', d(0) = 0, d'(0) = speed, integrated
    by scipy to d = 0 again."""
    log_e = math.log(restitution) if restitution < 1.0 else 0.0
    beta = abs(log_e) / math.sqrt(log_e ** 2 + math.pi ** 2)

    def rhs(t, y):
        d = max(y[0], 0.0)
        stiffness = 2.0 * e_star * math.sqrt(r_star * d)
        force = (4.0 / 3.0 * e_star * math.sqrt(r_star) * d ** 1.5
                 + 2.0 * math.sqrt(5.0 / 6.0) * beta * math.sqrt(stiffness * m_star) * y[1])
        return [y[1], -force / m_star]

    def separated(t, y):
        return y[0]
    separated.terminal = True
    separated.direction = -1
    scale = 2.87 * (m_star ** 2 / (r_star * e_star ** 2 * speed)) ** 0.2
    solution = solve_ivp(rhs, [0.0, 10 * scale], [0.0, speed], events=separated,
                         rtol=1e-10, atol=1e-16, max_step=scale / 2000, first_step=scale / 1e6)
    return float(solution.t_events[0][-1]), float(-solution.y_events[0][-1][1] / speed)


def flat_mesh(half_width, cells, material, height=0.0):
    """Square [-w, w]^2 at z = height of cells x cells squares, two triangles each (every
    inner vertex is shared by six triangles)."""
    ticks = np.linspace(-half_width, half_width, cells + 1)
    gx, gy = np.meshgrid(ticks, ticks, indexing="ij")
    vertices = np.column_stack([gx.ravel(), gy.ravel(), np.full(gx.size, height)])
    index = np.arange(gx.size).reshape(gx.shape)
    a, b = index[:-1, :-1].ravel(), index[1:, :-1].ravel()
    c, d = index[1:, 1:].ravel(), index[:-1, 1:].ravel()
    triangles = np.concatenate([np.column_stack([a, b, c]), np.column_stack([a, c, d])])
    return MeshWall(vertices, triangles, material)


def collide(model, state, *, walls=(), settings=None, safety_factor=0.01, max_steps=20000):
    """Step until a contact has come and gone. Returns (simulation, steps in contact)."""
    sim = bondem.Simulation(model, state, contact=settings or ContactSettings(), walls=walls,
                            safety_factor=safety_factor)
    in_contact = 0
    for _ in range(max_steps):
        sim.step(1)
        touching = sum(sim.contacts.touching())
        in_contact += touching > 0
        if in_contact and not touching:
            return sim, in_contact
    raise AssertionError("the contact did not end")

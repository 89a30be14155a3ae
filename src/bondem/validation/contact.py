"""Hertz contact: coefficient of restitution and contact time vs theory.

Two equal spheres (radius R, mass m) approach head-on at relative speed v. With
E* = E / (2 (1 - nu^2)), R* = R/2, m* = m/2 and the overlap delta:
    m* delta'' = -(4/3) E* sqrt(R*) delta^(3/2) + 2 sqrt(5/6) beta sqrt(S_n m*) delta'
    S_n = 2 E* sqrt(R* delta),  beta = ln e / sqrt(ln^2 e + pi^2) < 0   (Tsuji / EDEM;
  the damping opposes the overlap rate)
- e = 1: Hertz's contact time t_c = 2.87 (m*^2 / (R* E*^2 v))^(1/5) (Johnson 1985) and
  restitution 1.
- e < 1: the same ODE integrated with scipy (solve_ivp, rtol 1e-10) until delta returns
  to 0 gives the reference restitution and contact time of this damping law.
Uses ``bondem.contacts.ContactSettings`` (the contact module); when it is not available
the case reports "skipped: contacts not available".
"""
import math

import numpy as np

import bondem

from .core import CaseResult, Plot, Series, case, compare, skipped


def damped_hertz_reference(e, radius, mass, young, poisson, speed):
    """(restitution, contact time in s) of the damped Hertz ODE for a head-on impact of
    two equal spheres at relative speed ``speed`` (m/s)."""
    from scipy.integrate import solve_ivp
    e_star = young / (2 * (1 - poisson ** 2))
    r_star, m_star = radius / 2, mass / 2
    beta = math.log(e) / math.sqrt(math.log(e) ** 2 + math.pi ** 2) if e < 1 else 0.0

    def rhs(t, y):
        delta, rate = y
        d = max(delta, 0.0)
        stiffness = 2 * e_star * math.sqrt(r_star * d)
        force = -(4 / 3) * e_star * math.sqrt(r_star) * d ** 1.5 \
            + 2 * math.sqrt(5 / 6) * beta * math.sqrt(stiffness * m_star) * rate
        return [rate, force / m_star]

    def separated(t, y):
        return y[0]
    separated.terminal, separated.direction = True, -1
    t_hertz = 2.87 * (m_star ** 2 / (r_star * e_star ** 2 * speed)) ** 0.2
    solution = solve_ivp(rhs, (0, 10 * t_hertz), [1e-300, speed], events=separated,
                         rtol=1e-10, atol=1e-20, max_step=t_hertz / 200)
    t_end = solution.t_events[0][0]
    return -solution.y_events[0][0][1] / speed, t_end


def simulate(p, compat, e, ContactSettings):
    """bondem's (restitution, contact time in s, time step) for restitution ``e``."""
    radius, gap, speed = (p["particles"][k] for k in ("radius", "gap", "speed"))
    material = bondem.Material(density=p["material"]["density"],
                               young_modulus=p["material"]["young_modulus"],
                               poisson_ratio=p["material"]["poisson_ratio"],
                               restitution=e, friction=p["material"]["friction"])
    x = radius + gap / 2
    model, state = bondem.make_system([[-x, 0, 0], [x, 0, 0]], radius, material,
                                      velocity=[[speed, 0, 0], [-speed, 0, 0]])
    e_star = material.young_modulus / (2 * (1 - material.poisson_ratio ** 2))
    t_hertz = 2.87 * ((model.mass[0] / 2) ** 2
                      / (radius / 2 * e_star ** 2 * 2 * speed)) ** 0.2
    sim = bondem.Simulation(model, state, time_step=t_hertz / p["run"]["steps_per_contact"],
                            musen_compat=compat == "musen",
                            contact=ContactSettings("hertz_mindlin"))
    dt = sim.time_step
    sim.step(0)
    in_contact, start, end = False, None, None
    limit = int(20 * gap / speed / dt) + 200000
    for _ in range(limit):
        sim.step(1)
        distance = state.position[1, 0] - state.position[0, 0]
        if distance < 2 * radius and not in_contact:
            in_contact, start = True, _crossing(state.time, dt, distance, 2 * radius, speed)
        elif in_contact and distance >= 2 * radius:
            separation = state.velocity[1, 0] - state.velocity[0, 0]
            end = state.time - (distance - 2 * radius) / max(separation, 1e-300)
            break
    if start is None or end is None:
        return math.nan, math.nan, dt
    relative = state.velocity[1, 0] - state.velocity[0, 0]
    return relative / (2 * speed), end - start, dt


def _crossing(time, dt, distance, contact_distance, speed):
    # Overlap starts between two steps; interpolate with the approach speed.
    return time - (contact_distance - distance) / (2 * speed)


@case("contact", quick=True)
def run(p, compat, quick=False):
    """Hertz head-on impact: restitution and contact time vs Hertz / damped-Hertz ODE."""
    try:
        from bondem.contacts import ContactSettings
    except ImportError:
        return CaseResult([skipped("contact", "Hertz restitution and contact time",
                                   "contacts not available")])
    radius, speed = p["particles"]["radius"], 2 * p["particles"]["speed"]
    mass = p["material"]["density"] * 4 / 3 * np.pi * radius ** 3
    young, poisson = p["material"]["young_modulus"], p["material"]["poisson_ratio"]
    rows, points = [], []
    for e in p["run"]["restitutions"]:
        try:
            restitution, contact_time, dt = simulate(p, compat, e, ContactSettings)
        except TypeError as error:  # Simulation without a contact argument
            return CaseResult([skipped("contact", "Hertz restitution and contact time",
                                       f"contacts not available ({error})")])
        e_ref, t_ref = damped_hertz_reference(e, radius, mass, young, poisson, speed)
        if e == 1.0:
            e_star = young / (2 * (1 - poisson ** 2))
            t_ref = 2.87 * ((mass / 2) ** 2 / (radius / 2 * e_star ** 2 * speed)) ** 0.2
        time_tolerance = p["run"]["tolerance_time"]
        rows.append(compare("contact", f"e={e:g}: restitution", e_ref, restitution,
                            p["run"]["tolerance_restitution"]))
        rows.append(compare("contact", f"e={e:g}: contact time (s)", t_ref, contact_time,
                            time_tolerance))
        points.append((e, restitution, e_ref))
    plot = Plot("Hertz head-on impact: restitution", "material restitution e",
                "measured restitution",
                [Series("bondem", [x for x, _, _ in points], [y for _, y, _ in points], "o"),
                 Series("damped Hertz ODE", [x for x, _, _ in points],
                        [z for _, _, z in points], "x")])
    return CaseResult(rows, [plot])

"""Fluids and fields (physics/field_fluid.py, physics/field_frame.py, docs/fields.md)
against closed forms and a second way of computing the same motion:
- a sphere settling in a still fluid: Stokes' terminal velocity
  (rho_p - rho_f) g d^2 / (18 mu) and the velocity at which Schiller and Naumann's drag
  balances the weight less the buoyancy near Re = 100 (brentq on the drag law's C_d);
- a sphere as dense as the fluid stays where it is;
- a rotating drum (a bowl turning about the vertical, gravity along it): particles in the
  bowl's rotating frame, with its walls at rest, against the same particles in the
  laboratory with the bowl as a turning mesh wall, their positions mapped into the frame,
  R(-Omega t) (x - c) + c. Hertz-Mindlin contacts with friction, between the particles
  and with the floor and side; the full suite only (10 s).
"""
import math

import numpy as np
from scipy.optimize import brentq

import bondem
from bondem.contacts import ContactSettings
from bondem.model import fluid_array, frame_array
from bondem.physics.field_fluid import DRAG_LAWS, drag_coefficient
from bondem.walls import MeshWall, rotation_matrix

from .core import CaseResult, case, compare

CASE = "fields"
GRAVITY = 9.81


def _sphere(rho_p, d, fluid, gravity=(0.0, 0.0, -GRAVITY)):
    glass = bondem.Material(name="p", density=rho_p, young_modulus=1e9, poisson_ratio=0.3)
    return bondem.make_system(np.array([[1e-3, -2e-3, 5e-3]]), np.array([0.5 * d]), [glass],
                              gravity=gravity, fluid=fluid)


def _stokes(p):
    s = p["stokes"]
    rho_p, rho_f, mu, d = s["particle_density"], s["density"], s["viscosity"], s["diameter"]
    model, state = _sphere(rho_p, d, fluid_array(density=rho_f, viscosity=mu,
                                                 drag="stokes", buoyancy=True))
    tau = rho_p * d * d / (18.0 * mu)
    sim = bondem.Simulation(model, state, time_step=tau / 400, force_time_step=True)
    sim.run(until=15 * tau)
    terminal = (rho_p - rho_f) * d * d * GRAVITY / (18.0 * mu)
    return [compare(CASE, "Stokes settling: terminal velocity (m/s)", terminal,
                    -sim.state.velocity[0, 2], s["tolerance"],
                    note="(rho_p - rho_f) g d^2 / (18 mu), at 15 relaxation times")]


def _schiller_naumann(p):
    s = p["schiller_naumann"]
    rho_p, rho_f, mu, d = s["particle_density"], s["density"], s["viscosity"], s["diameter"]
    weight = (rho_p - rho_f) * math.pi / 6.0 * d ** 3 * GRAVITY
    law = DRAG_LAWS["schiller_naumann"]

    def balance(v):
        re = rho_f * v * d / mu
        return 0.5 * rho_f * drag_coefficient(law, re) * math.pi / 4 * d * d * v * v - weight

    terminal = brentq(balance, 1e-6, 10.0, xtol=1e-14)
    model, state = _sphere(rho_p, d, fluid_array(density=rho_f, viscosity=mu,
                                                 drag="schiller_naumann", buoyancy=True))
    sim = bondem.Simulation(model, state, time_step=s["time_step"], force_time_step=True)
    sim.run(until=s["time"])
    re = rho_f * terminal * d / mu
    return [compare(CASE, f"Schiller-Naumann settling at Re = {re:.0f}: terminal velocity "
                    "(m/s)", terminal, -sim.state.velocity[0, 2], s["tolerance"],
                    note="drag = weight - buoyancy (brentq)")]


def _neutral(p):
    s = p["neutral"]
    model, state = _sphere(s["density"], s["diameter"],
                           fluid_array(density=s["density"], viscosity=s["viscosity"],
                                       drag="schiller_naumann", buoyancy=True))
    start = state.position.copy()
    sim = bondem.Simulation(model, state, time_step=s["time_step"], force_time_step=True)
    sim.run(until=s["time"])
    moved = float(np.linalg.norm(sim.state.position - start))
    return [compare(CASE, "a sphere as dense as the fluid: distance moved (m)", 0.0, moved,
                    1e-15, absolute=True, note="buoyancy = weight")]


def drum_runs(d, times):
    """The rotating drum of the module docstring, parameters ``d`` (the TOML's [drum]):
    run once in the bowl's frame and once in the laboratory with the bowl turning. Returns
    [(t (s), frame positions (N,3) m, laboratory positions mapped into the frame (N,3) m,
    frame spins (N,3) rad/s, laboratory spins mapped (N,3) rad/s)] at each of ``times``."""
    import trimesh
    radius, r = d["radius"], d["particle_radius"]
    omega = np.array([0.0, 0.0, d["angular_velocity"]])
    center = np.array(d["center"], dtype=float)
    material = bondem.Material(name="p", density=d["density"],
                               young_modulus=d["young_modulus"],
                               poisson_ratio=d["poisson_ratio"],
                               restitution=d["restitution"], friction=d["friction"])
    bowl = trimesh.creation.cylinder(radius=radius, height=1.5 * radius,
                                     sections=d["sections"])
    bowl.apply_translation([center[0], center[1], 0.75 * radius])
    position = np.array(d["positions"], dtype=float) + [center[0], center[1], 0.0]
    gravity = (0.0, 0.0, -GRAVITY)
    runs = []
    for frame in (True, False):
        if frame:
            wall = MeshWall(bowl.vertices, bowl.faces, material)
            model, state = bondem.make_system(position, r, material, gravity=gravity,
                                              frame=frame_array(omega, center))
        else:
            wall = MeshWall(bowl.vertices, bowl.faces, material, angular_velocity=omega,
                            rotation_center=center)
            # at rest in the bowl: carried round by it
            model, state = bondem.make_system(
                position, r, material, gravity=gravity,
                velocity=np.cross(omega, position - center),
                angular_velocity=np.tile(omega, (len(position), 1)))
        sim = bondem.Simulation(model, state, time_step=d["time_step"],
                                force_time_step=True,
                                contact=ContactSettings(model="hertz_mindlin"), walls=[wall])
        rows = []
        for t in times:
            sim.run(until=t)
            rows.append((sim.state.time, sim.state.position.copy(),
                         sim.state.angular_velocity.copy()))
        runs.append(rows)
    out = []
    for (t, x, w), (_, x_lab, w_lab) in zip(*runs):
        back = rotation_matrix(-omega, t)
        # the leapfrog's spins are half a step behind the positions
        back_w = rotation_matrix(-omega, t - 0.5 * d["time_step"])
        out.append((t, x, (x_lab - center) @ back.T + center, w, w_lab @ back_w.T - omega))
    return out


def _drum(p):
    d = p["drum"]
    t, x, mapped, w, w_mapped = drum_runs(d, [d["time"]])[-1]
    at_wall = float(np.min(np.linalg.norm((x - d["center"])[:, :2], axis=1)))
    return [compare(CASE, "rotating drum: frame against turning wall, max position "
                    "difference (of the drum radius)", 0.0,
                    float(np.abs(x - mapped).max()) / d["radius"], d["tolerance"],
                    absolute=True, note=f"{len(x)} spheres at t = {t:.2f} s"),
            compare(CASE, "rotating drum: max spin difference (of Omega)", 0.0,
                    float(np.abs(w - w_mapped).max()) / d["angular_velocity"],
                    d["spin_tolerance"], absolute=True),
            compare(CASE, "rotating drum: nearest sphere centre to the axis (m)",
                    d["radius"] - d["particle_radius"], at_wall, 0.05,
                    note="all thrown out against the side")]


@case(CASE, quick=True)
def run(p, compat, quick=False):
    """Fields: Stokes and Schiller-Naumann settling, neutral buoyancy, and (full suite) a
    rotating drum in its frame against the drum as a turning wall."""
    rows = _stokes(p) + _schiller_naumann(p) + _neutral(p)
    if not quick:
        rows += _drum(p)
    return CaseResult(rows)

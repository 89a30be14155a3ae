"""Angle of repose of a collapsed column: L-trimer clumps (no bonds) against spheres of
the same material and friction (docs/clumps.md). A column of 16 x 6 x 60 mm (periodic
across its 6 mm) against a wall at x = 0 on a floor collapses; the angle is the slope of
the heap's top (highest sphere per 2 mm of x) between 20 % and 80 % of its height.

    python scripts/angle_of_repose.py clumps|spheres [rolling_friction]
"""
import sys, time, json
import numpy as np
import bondem
from bondem.clumps import ClumpTemplate, pack_clumps, make_clumps
from bondem.generate import Box, pack_spheres
from bondem.contacts import ContactSettings
from bondem.walls import PlaneWall
kind = sys.argv[1]
r = 1e-3
mat = bondem.Material(name="m", density=2500.0, young_modulus=2e7, poisson_ratio=0.25,
                      restitution=0.3, friction=0.5, rolling_friction=float(sys.argv[2]) if len(sys.argv) > 2 else 0.0)
H, W, T = 60e-3, 16e-3, 6e-3   # column height, width (x), thickness (y, periodic)
box = Box(low=(0.05e-3, 0.0, 0.05e-3), high=(W, T, H))
if kind == "clumps":
    tpl = ClumpTemplate([[0, 0, 0], [1.6 * r, 0, 0], [0, 1.6 * r, 0]], [r, r, 0.8 * r])
    pk = pack_clumps(box, tpl, 2500.0, solids_fraction=0.35, seed=3, compact=0.8)
    pos, rad = pk["position"], pk["radius"]
else:
    pos, rad = pack_spheres(box, radius=r, solids_fraction=0.45, seed=3)
# periodic y: members may stick out of the cell; wrap them
pos[:, 1] = np.mod(pos[:, 1], T)
model, state = bondem.make_system(pos, rad, mat, gravity=(0, 0, -9.81), periodic=(False, True, False),
                                  box_low=(-1, 0, -1), box_high=(1, T, 1))
if kind == "clumps":
    model, state = make_clumps(model, state, pk["clump_of"], mass=pk["mass"], inertia=pk["inertia"], centre=pk["centre"])
walls = [PlaneWall((0, 0, 0), (0, 0, 1), mat), PlaneWall((0, 0, 0), (1, 0, 0), mat)]
sim = bondem.Simulation(model, state, contact=ContactSettings(), walls=walls)
print(kind, model.n_particles, "particles", model.n_clumps, "clumps, dt", sim.time_step, flush=True)
t0 = time.time()
while sim.state.time < 1.0:
    sim.run(until=sim.state.time + 0.05)
    ke = sum(sim.kinetic_energy())
    print(f"t={sim.state.time:.2f} ke={ke:.3e} wall {time.time()-t0:.0f}s", flush=True)
    if sim.state.time > 0.3 and ke < 1e-9:
        break
x, z = sim.state.position[:, 0], sim.state.position[:, 2] + model.radius
edges = np.arange(0.0, x.max() + 2e-3, 2e-3)
tops = []
for a, b in zip(edges[:-1], edges[1:]):
    sel = (x >= a) & (x < b)
    if sel.sum() >= 2:
        tops.append((0.5 * (a + b), z[sel].max()))
tops = np.array(tops)
# the slope between 20 % and 80 % of the heap's height
h = tops[:, 1]
use = (h > 0.2 * h.max()) & (h < 0.8 * h.max())
slope = np.polyfit(tops[use, 0], tops[use, 1], 1)[0] if use.sum() >= 2 else float("nan")
angle = float(np.degrees(np.arctan(-slope)))
print(json.dumps({"kind": kind, "angle": angle, "height": float(h.max()), "runout": float(x.max()), "time": sim.state.time}))

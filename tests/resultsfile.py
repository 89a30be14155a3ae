"""A tiny SPEC 6 results writer for the analysis tests (the real writer lives in
bondem.io.results): records frames of a Simulation and writes them with h5py."""
import h5py
import numpy as np

PER_FRAME = {"particles/position": "position", "particles/velocity": "velocity",
             "particles/angular_velocity": "angular_velocity", "bonds/active": "bond_active"}


class Recorder:
    """Callback for ``Simulation.run(callback=...)``: keeps a copy of every frame."""

    def __init__(self, sim):
        self.model = sim.model
        self.frames = []
        self(sim)

    def __call__(self, sim):
        s = sim.state
        frame = {"time": s.time, "energy": sim.energy_terms(),
                 "break_mode": s.bond_break_mode.copy(), "break_time": s.bond_break_time.copy(),
                 "bond_force": np.zeros((sim.model.n_bonds, 3))}
        frame.update({key: getattr(s, attr).copy() for key, attr in PER_FRAME.items()})
        self.frames.append(frame)


def write(path, model, frames, walls=None):
    """Write ``frames`` (from Recorder) in the SPEC 6 layout plus the extras.
    walls: optional {"force": (F,W,3), "position": (F,W,3)}."""
    with h5py.File(path, "w") as f:
        f["time"] = np.array([fr["time"] for fr in frames])
        f["particles/radius"] = model.radius
        f["particles/mass"] = model.mass
        f["particles/material"] = model.material
        f["materials/names"] = np.array([m.name for m in model.materials], dtype="S")
        f["bonds/pairs"] = model.bond_pairs
        f["bonds/diameter"] = model.bond_diameter
        f["bonds/initial_length"] = model.bond_initial_length
        f["bonds/break_time"] = frames[-1]["break_time"]
        f["bonds/break_mode"] = frames[-1]["break_mode"]
        f["bonds/force"] = np.stack([fr["bond_force"] for fr in frames])
        for key in PER_FRAME:
            f[key] = np.stack([fr[key] for fr in frames])
        for name in frames[0]["energy"]:
            f[f"energy/{name}"] = np.array([fr["energy"][name] for fr in frames])
        n_walls = 0 if walls is None else walls["force"].shape[1]
        f["walls/force"] = np.zeros((len(frames), n_walls, 3)) if walls is None else walls["force"]
        f["walls/position"] = (np.zeros((len(frames), n_walls, 3)) if walls is None
                               else walls["position"])
        f.attrs["bondem_version"] = "test"
    return path


def write_static(path, position, radius, pairs, active, time=None, mass=None, break_mode=None,
                 walls=None, energy=None):
    """Write a file from plain arrays: position (F,N,3) or (N,3), active (F,B)."""
    active = np.atleast_2d(np.asarray(active, dtype=bool))
    n_frames = active.shape[0]
    position = np.asarray(position, dtype=float)
    if position.ndim == 2:
        position = np.broadcast_to(position, (n_frames,) + position.shape)
    with h5py.File(path, "w") as f:
        f["time"] = np.arange(n_frames, dtype=float) if time is None else time
        f["particles/radius"] = np.broadcast_to(radius, position.shape[1:2]).astype(float)
        if mass is not None:
            f["particles/mass"] = mass
        f["particles/position"] = position
        f["bonds/pairs"] = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
        f["bonds/active"] = active
        if break_mode is not None:
            f["bonds/break_mode"] = np.asarray(break_mode, dtype=np.int8)
        if walls is not None:
            f["walls/force"], f["walls/position"] = walls
        for name, values in (energy or {}).items():
            f[f"energy/{name}"] = values
    return path


def two_halves(glass, *, speed=0.5, strength=2e5, safety_factor=0.01, damping=0.1,
               seed=0):
    """A 4x3x3 bonded block (36 particles, radius 1 mm, touching) whose left and right
    halves fly apart at +-speed (m/s, plus 10 % noise). Bonds within a half never break;
    the 33 bonds across the middle plane have strength ``strength`` (Pa), low enough that
    all of them break. Returns (simulation, cut (B,) bool: the bonds across the plane)."""
    import bondem

    grid = np.stack(np.meshgrid(np.arange(4), np.arange(3), np.arange(3), indexing="ij"),
                    -1).reshape(-1, 3)
    position = grid * 2e-3
    distance = np.linalg.norm(position[:, None] - position[None], axis=-1)
    i, j = np.nonzero(np.triu(distance < 2.9e-3, 1))   # nearest and face-diagonal pairs
    left = grid[:, 0] < 1.5
    cut = left[i] != left[j]
    strong = bondem.BondMaterial(young_modulus=1e8, breakage="none", name="strong")
    weak = bondem.BondMaterial(young_modulus=1e8, normal_strength=strength,
                               tangential_strength=strength, name="weak")
    rng = np.random.default_rng(seed)
    velocity = (np.where(left[:, None], [-speed, 0.0, 0.0], [speed, 0.0, 0.0])
                + rng.normal(0.0, 0.1 * speed, position.shape))
    model, state = bondem.make_system(position, 1e-3, glass, velocity=velocity,
                                      bonds=np.column_stack([i, j]), bond_diameter=1e-3,
                                      bond_material=[strong, weak],
                                      bond_material_index=cut.astype(int), damping=damping)
    return bondem.Simulation(model, state, safety_factor=safety_factor), cut


def record_run(sim, until, every):
    """Run ``sim`` to ``until`` (s) keeping a frame every ``every`` (s); returns frames."""
    recorder = Recorder(sim)
    sim.run(until, every=every, callback=recorder)
    return recorder.frames

"""bondem: discrete element simulation of bonded particles (MUSEN's elastic solid bond)."""
from .model import BondMaterial, Material, Model, State, make_system
from .status import SimulationBlowUp
from .simulation import Simulation
from .contacts import ContactSettings
from .walls import MeshWall, PlaneWall
from .scene import load_scene
from .runner import run_scene
from .timestep import stable_time_step, time_scales

from ._version import __version__

__all__ = ["BondMaterial", "Material", "Model", "State", "make_system", "Simulation",
           "SimulationBlowUp", "ContactSettings", "PlaneWall", "MeshWall", "load_scene",
           "run_scene", "stable_time_step", "time_scales", "__version__"]

"""plugsim engine: one case of grains (DEM) and gas in a tube.

Public API: `Case` (validated configuration), `Simulation` (advance a case in time).
"""

from .case import Case, CaseError, KEYS
from .simulation import Simulation, SimulationError

__version__ = "0.2.0"
__all__ = ["Case", "CaseError", "KEYS", "Simulation", "SimulationError", "__version__"]

"""Index names of the float64 parameter vector passed to the grain kernels (SI units)."""

import numpy as np

DT = 0               # time step, s
MASS = 1             # grain mass, kg
RADIUS = 2           # grain radius, m
INERTIA = 3          # moment of inertia 2/5 m r^2, kg m2
KN = 4               # normal stiffness, N/m
GN_PAIR = 5          # normal damping grain-grain, N s/m
GN_WALL = 6          # normal damping grain-wall, N s/m
GT = 7               # tangential damping grain-grain, gamma_t capped at (m/7)/dt, N s/m
MU_PAIR = 8          # Coulomb coefficient grain-grain
MU_WALL = 9          # Coulomb coefficient grain-wall
TUBE_RADIUS = 10     # m
TUBE_LENGTH = 11     # m
GX = 12              # gravity vector, m/s2
GY = 13
GZ = 14
FEED_SPEED = 15      # feed piston speed u_in, m/s (0: no feed)
FEED_MAX_OVERLAP = 16  # the tube is blocked when the piston presses a grain deeper than this, m
SKIN = 17            # Verlet skin, m
CELL_X0 = 18         # lower x edge of the cell grid, m
CELL_DX = 19         # cell size along x, m
CELL_DYZ = 20        # cell size across, m
ROTATION = 21        # 1.0: integrate rotation; 0.0: frictionless, rotation skipped
GAS_ON = 22          # 1.0: couple the gas every GAS_INTERVAL steps
GAS_INTERVAL = 23    # grain steps per gas update
GAS_THETA = 24       # theta of the gas time scheme
FEED_VOLUME_RATE = 25  # m_dot / rho_s, m3/s: gas displaced by the entering grains
GT_WALL = 26         # tangential damping grain-wall, gamma_t capped at (2m/7)/dt, N s/m
IMPLICIT_SPIN = 27   # 1.0: spin kicks scaled by 1/(1 + dt sum(gamma_t) r^2/I) of the viscous contacts
FEED_BLOCK_STEPS = 28  # consecutive steps above FEED_MAX_OVERLAP that make the tube blocked
ROLLING_RESISTANCE = 29  # rolling-resistance coefficient mu_r (0: off)
NPARAMS = 30

# Slots that hold a case key's value as it is (filled by Simulation._setup_params)
FROM_CASE = {ROLLING_RESISTANCE: "particles.rolling_resistance"}

# Integer cell-grid shape vector
NCX = 0
NCY = 1
NCZ = 2

# Counters (int64 vector, cumulative unless noted)
RELEASED = 0         # feed grains released into the tube
REMOVED = 1          # grains that left past x = L
REBUILDS = 2         # neighbour-list rebuilds
STEPS = 3            # steps taken
STATUS = 4           # 0 ok; >0 failure code (not cumulative)
OVERFLOW = 5         # neighbour list overflowed (not cumulative; caller grows the list)
PRESSED_STEPS = 6    # consecutive steps the piston has pressed a grain beyond FEED_MAX_OVERLAP
NCOUNTERS = 7

# failure codes
OK = 0
NONFINITE = 1
ESCAPED = 2
BLOCKED = 3          # the enforced feed cannot push: piston overlap above FEED_MAX_OVERLAP

# Float diagnostics vector `diag` (m, N s)
DIAG_OVERLAP = 0       # max overlap of dynamic grains in the last force evaluation, m
DIAG_FEED_OVERLAP = 1  # max overlap of a feed grain with a tube grain, last evaluation, m
DIAG_RUNNING_MAX = 2   # running max of both since Simulation.reset_max_overlap, m
DIAG_PISTON_IMPULSE = 3  # cumulative axial impulse of the feed piston on the tube grains, N s
NDIAG = 4


def new_params() -> np.ndarray:
    return np.zeros(NPARAMS)

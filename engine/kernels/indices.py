"""Index names of the kernels' integer and float state vectors: the cell-grid shape, the counters,
the failure codes and the diagnostics (the kernels' parameters are named tuples, engine/parameters.py)."""

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
PRESSED_STEPS = 6    # consecutive steps the piston has pressed a grain beyond p.feed_max_overlap
NCOUNTERS = 7

# failure codes
OK = 0
NONFINITE = 1
ESCAPED = 2
BLOCKED = 3          # the enforced feed cannot push: piston overlap above p.feed_max_overlap

# Float diagnostics vector `diag` (m, N s)
DIAG_OVERLAP = 0       # max overlap of dynamic grains in the last force evaluation, m
DIAG_FEED_OVERLAP = 1  # max overlap of a feed grain with a tube grain, last evaluation, m
DIAG_RUNNING_MAX = 2   # running max of both since Simulation.reset_max_overlap, m
DIAG_PISTON_IMPULSE = 3  # cumulative axial impulse of the feed piston on the tube grains, N s
NDIAG = 4


"""The kernels' state bundles: named tuples of arrays, built by engine.simulation.Simulation."""

from collections import namedtuple

# Per-grain arrays, rows 0..n-1 in use: centres, velocities, spins (m, m/s, rad/s); contact force and
# gas drag (N); torque (N m); the sum of gamma_t of the grain's contacts in their viscous branch
# (N s/m, the implicit spin kick's denominator, numerics.implicit_spin); normal force of the cylinder
# (N); id; 1 for a grain of the feed piston (held kinematically); centre at the last neighbour-list
# build (m).
Grains = namedtuple("Grains",
                    "pos vel omg force drag torque viscous_damping wall_normal gid in_feed pos_ref")

# Cell grid and half neighbour list: grid shape (ncx, ncy, ncz), cell starts, each grain's cell,
# sort order and sort work arrays, list starts per grain, the list (partners) and each entry's grain
# (p.cell_*, p.skin).
Neighbors = namedtuple("Neighbors", "shape cell_start cell_of order tmp3 tmpi nbr_start nbr nbr_i")

# Thread work arrays of contacts.evaluate_contacts: spill rows of forces, torques and viscous damping
# sums per chunk (zero between calls), chunk bounds (nchunks + 1), per-chunk diagnostics, touching
# contacts per grain.
Chunks = namedtuple("Chunks",
                    "spill_force spill_torque spill_viscous_damping bounds chunk_diag contact_count")

# Work arrays of the one-thread contact passes (passes.contact_passes), for one block of passes.BLOCK
# list entries: the touching pairs' grains (pair_i, pair_j), one row of `rows` per quantity of a pair
# (passes.ROWS, BLOCK values each: inputs gathered contiguously, outputs of the pair law).
Pairs = namedtuple("Pairs", "pair_i pair_j rows")

"""Multiple-aircraft landing planner: scenario models, RRT initializer, pseudospectral optimizer.

The planning core (everything except :mod:`mal_planner.ros`) imports nothing from ROS.
Inside the planner all quantities use the thesis's units: nautical miles, seconds, radians.
"""

import os

# CasADi's bundled OpenBLAS (used by MUMPS in IPOPT) starts a busy-waiting thread per core. On the
# NLP sizes here it brings no speed-up (measured: same wall time) but burns a core in system time
# (10 aircraft: 10 s of 18 s wall), which slows everything else on the machine (campaign workers, the node's
# figure process). Set before CasADi loads; a user's own setting is kept.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

"""Does a policy fall under a steady level acceleration that it survives as the equivalent tilt?

    python scripts/level_acceleration_probe.py --checkpoint resources/policies/lasmp_a1.pt --out DIR
    python scripts/level_acceleration_probe.py --controller stand_still --out DIR

Plays lasmp.motions.level_push's three 20-s motions (a level push at 1.5 m/s², its equivalent tilt,
a slow ramp to the same speed) as the real-motion suite plays its scenarios (the benchmark's first 64
robots, the close platform drive; any `evaluate.py --suite` option passes through). docs/real_motion.md,
"The shipped policy in the final world", reports what it found.
"""

from __future__ import annotations

import sys

from lasmp.eval import cli
from lasmp.motions.level_push import motions

if __name__ == "__main__":
    sys.exit(cli.main([*sys.argv[1:], "--suite", "real_motion"], motions=motions()))

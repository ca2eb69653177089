"""How close the simulated people come to each other: pair-seconds below a few centre distances.

    .venv/bin/python bench/bench_sim_crowding.py                          # moving, seeds 1-8, full length
    .venv/bin/python bench/bench_sim_crowding.py --scenario static rooms --seeds 1 2

Runs only the motion of each scenario and seed (no rendering, seconds per recording) and sums, over every
two people and every 20 ms step, the time their centres are closer than 0.3 / 0.45 / 0.6 / 1.0 m, and the
closest they ever come. Below 0.3 m two bodies overlap (shoulders are ~0.45 m wide): only two people
squeezing past each other in a door passage should get there. It also prints the longest time anyone stood
still on their way somewhere (not a stop at a goal): someone boxed in gives up their goal after 4 s, so a
longer standstill is a trap (version 4: 72 s in a door passage, moving seed 1).
"""

from __future__ import annotations

import argparse

import numpy as np

from studio.sim import SCENARIOS
from studio.sim import motion as sim_motion
from studio.sim.scenarios import get_scenario
from studio.sim.simulate import SIM_VERSION
from studio.sim.world import build_world

LIMITS = (0.3, 0.45, 0.6, 1.0)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--scenario", nargs="+", default=["moving"], choices=list(SCENARIOS))
    ap.add_argument("--seeds", nargs="+", type=int, default=list(range(1, 9)))
    args = ap.parse_args()
    world = build_world()
    print(f"simulator version {SIM_VERSION}; pair-seconds closer than {' / '.join(map(str, LIMITS))} m")
    for name in args.scenario:
        sc = get_scenario(name)
        total, closest, still = np.zeros(len(LIMITS)), np.inf, 0.0
        for seed in args.seeds:
            # the motion's share of the seed, as simulate() draws it
            r_motion, _, _ = np.random.default_rng(np.random.SeedSequence(seed)).spawn(3)
            m = sim_motion.simulate_motion(sc, world, seconds=sc.seconds, rng=r_motion)
            P = m.people[..., :2].transpose(1, 0, 2)  # (time, person, 2)
            d = np.linalg.norm(P[:, :, None, :] - P[:, None, :, :], axis=-1)
            iu = np.triu_indices(P.shape[1], 1)
            pairs = d[:, iu[0], iu[1]]
            seen = np.array([(pairs < r).sum() * sim_motion.DT for r in LIMITS])
            low = float(pairs.min()) if pairs.size else np.inf
            stood = float(m.standstill_s.max(initial=0.0))
            total += seen
            closest = min(closest, low)
            still = max(still, stood)
            print(
                f"{name} seed {seed}: " + " / ".join(f"{v:.1f}" for v in seen) + f" s, closest {low:.2f} m, "
                f"longest standstill {stood:.1f} s"
            )
        print(
            f"{name} total: " + " / ".join(f"{v:.1f}" for v in total) + f" s, closest {closest:.2f} m, "
            f"longest standstill {still:.1f} s"
        )


if __name__ == "__main__":
    main()

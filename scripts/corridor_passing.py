"""How low can ground-truth ``m_psi`` go in ``corridor``? Scripted drivers handed the true
people, on the same episodes as the models.

    python scripts/corridor_passing.py --episodes 200 --seed 20000000

``m_psi`` (METRICS.md) is a time average: the largest personal-space intrusion of each
sample, averaged over the samples at which someone is present. In ``SRPB-Corridor-v0``
(2.2 m wide) two people walk the corridor towards the robot, so every driver meets them;
what a driver can choose is its lane, its speed and when it sets off. Each driver here
keeps a lane (``y`` [m] from the lower wall; the people walk along y = 1.1 +- 0.25) at the
robot's top speed and then turns onto the goal; with ``wait`` it first stops in its lane at
the start until every person is behind it. The drivers know the true people (like the
reference planners, :mod:`srpb_gym.planners.reference`) and decide nothing else, so their
figures bound what lane, speed and waiting do, not what a planner can learn.

Reported per driver: success, the mean of ground-truth ``m_psi`` with a percentile
bootstrap 95 % interval (10,000 resamples, default_rng(0)), the mean of the episode
integral of the intrusion (``m_psi`` x the time someone is present / 100 [s]: what the
``psi`` reward term pays for, per unit weight) and the mean time to the goal ``m_mef``.
"""

from __future__ import annotations

import argparse
import math
import sys
from typing import Any

import gymnasium as gym
import numpy as np
from numpy.typing import NDArray

import srpb_gym  # noqa: F401  (registers the environments)
from srpb_gym.evaluation.intervals import bootstrap_mean
from srpb_gym.knowledge import Knowledge
from srpb_gym.planners.base import Planner, command_to_action, heading_error, knowledge_for
from srpb_gym.seeds import TEST

MIDDLE = 1.1  # m, the corridor's middle line


class LaneDriver(Planner):
    """Drive along the lane y = ``lane`` at top speed, then onto the goal and its heading;
    with ``wait``, first stop in the lane until every person is behind the robot; with
    ``ahead`` [m], keep to the corridor's middle (y = 1.1) but while someone is less than
    ``ahead`` in front of the robot or beside it."""

    name = "lane"
    ground_truth = True

    def __init__(self, lane: float, wait: bool = False, ahead: float | None = None) -> None:
        self.lane, self.wait, self.ahead = lane, wait, ahead
        self.waiting = wait

    def reset(self, knowledge: Knowledge) -> None:
        self.waiting = self.wait

    def act(self, observation: Any, knowledge: Knowledge) -> NDArray[np.float32]:
        x, y, yaw = knowledge.pose
        gx, gy, gyaw = knowledge.goal
        robot = knowledge.robot
        people_x = knowledge.tracks.xy[:, 0]
        lane = self.lane
        if self.ahead is not None and not np.any(
            (people_x > x - 0.5) & (people_x < x + self.ahead)
        ):
            lane = MIDDLE
        in_lane = abs(y - lane) < 0.1
        if self.waiting and in_lane and bool(np.all(people_x < x - 0.5)):
            self.waiting = False
        dist = math.hypot(gx - x, gy - y)
        if dist < 0.5 * knowledge.goal_tolerance:  # on the goal: turn to its heading
            err = math.remainder(gyaw - yaw, math.tau)
            return command_to_action(0.0, 0.0, float(np.clip(2.0 * err, -1, 1)) * robot.w_max,
                                     robot)  # fmt: skip
        if gx - x < 1.5:  # the last metres: onto the goal
            tx, ty = gx, gy
        else:  # along the lane, a metre ahead (a step aside at the start)
            tx, ty = x + (0.3 if self.waiting else 1.0), lane
        err = heading_error(knowledge, tx, ty)
        omega = float(np.clip(2.0 * err, -robot.w_max, robot.w_max))
        speed = robot.v_max * max(0.0, math.cos(err)) ** 4 * min(1.0, dist)
        if self.waiting and in_lane:
            speed = 0.0
            omega = float(np.clip(2.0 * math.remainder(-yaw, math.tau), -1, 1)) * robot.w_max
        return command_to_action(speed, 0.0, omega, robot)


def run(driver: LaneDriver, episodes: int, seed: int) -> dict[str, Any]:
    """The driver's figures over ``episodes`` episodes from ``seed``."""
    env = gym.make("SRPB-Corridor-v0")
    psi, integral, mef, obs_time, wins = [], [], [], [], 0
    for k in range(episodes):
        obs, _ = env.reset(seed=seed + k)
        task = env.unwrapped
        driver.reset(knowledge_for(driver, task.knowledge))
        present = 0.0
        while True:
            knowledge = knowledge_for(driver, task.knowledge)
            present += knowledge.control_dt if len(knowledge.tracks.xy) else 0.0
            obs, _, terminated, truncated, info = env.step(driver.act(obs, knowledge))
            if terminated or truncated:
                break
        wins += bool(info["is_success"])
        psi.append(info["srpb_gt/m_psi"])
        integral.append(info["srpb_gt/m_psi"] * present / 100.0)
        mef.append(info["srpb/m_mef"])
        obs_time.append(info["srpb/m_obs"])
    env.close()
    v = np.asarray(psi, dtype=np.float64)
    return {"success": 100.0 * wins / episodes, "m_psi": float(v.mean()),
            "ci": bootstrap_mean(v) or (math.nan, math.nan), "integral": float(np.mean(integral)),
            "m_mef": float(np.mean(mef)), "m_obs": float(np.mean(obs_time))}  # fmt: skip


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--episodes", type=int, default=200)
    parser.add_argument("--seed", type=int, default=TEST.start)
    parser.add_argument("--lanes", type=float, nargs="+", default=[0.45, 0.7, 1.1, 1.5, 1.75])
    parser.add_argument("--ahead", type=float, nargs="*", default=[3.0, 6.0],
                        help="drivers in the middle but when someone is this near [m]")  # fmt: skip
    args = parser.parse_args(argv)
    print(f"SRPB-Corridor-v0, {args.episodes} episodes from seed {args.seed}, ground truth")
    print(
        "| driver | success | mean m_psi [95 % CI] | mean intrusion integral [s] | "
        "m_mef [s] | m_obs [%] |"
    )
    print("| --- | ---: | ---: | ---: | ---: | ---: |")
    drivers = [(f"lane y = {lane:.2f} m", LaneDriver(lane)) for lane in args.lanes]
    drivers += [(f"lane y = {lane:.2f} m, waits for the people", LaneDriver(lane, wait=True))
                for lane in args.lanes]  # fmt: skip
    low = min(args.lanes)
    drivers += [(f"middle, y = {low:.2f} m when someone is within {a:g} m",
                 LaneDriver(low, ahead=a)) for a in args.ahead]  # fmt: skip
    for label, driver in drivers:
        f = run(driver, args.episodes, args.seed)
        print(f"| {label} | {f['success']:.1f} % | {f['m_psi']:.2f} [{f['ci'][0]:.2f}-"
              f"{f['ci'][1]:.2f}] | {f['integral']:.2f} | {f['m_mef']:.1f} | "
              f"{f['m_obs']:.1f} |", flush=True)  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())

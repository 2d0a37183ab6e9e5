"""Registration of the srpb-gym environment ids with Gymnasium."""

from __future__ import annotations

import math

import gymnasium as gym
import yaml
from gymnasium.envs.registration import WrapperSpec

from srpb_gym.resources import scenarios_dir

ENTRY_POINT = "srpb_gym.env:SRPBNavEnv"
CONTROL_DT = 0.1  # s, the default control step (srpb_gym.simulation.SimConfig)

#: environment id -> packaged scenario
SCENARIO_IDS: dict[str, str] = {
    "SRPB-Corridor-v0": "corridor",
    "SRPB-FFormation-v0": "fformation",
    "SRPB-Crossing-v0": "crossing",
    "SRPB-Crowd-v0": "crowd",
    "SRPB-Doorway-v0": "doorway",
}
#: packaged scenario -> its environment id
ENV_IDS: dict[str, str] = {scenario: env_id for env_id, scenario in SCENARIO_IDS.items()}
CUSTOM_ID = "SRPB-Custom-v0"
#: a scenario drawn at every reset (srpb_gym.mix.SRPBMixEnv)
MIX_ID = "SRPB-Mix-v0"
MIX_ENTRY_POINT = "srpb_gym.mix:SRPBMixEnv"
#: the scenarios of SRPB-Mix-v0 by default, drawn with equal weights
MIX_SCENARIOS: tuple[str, ...] = tuple(SCENARIO_IDS.values())
#: applied by gym.make outside TimeLimit: tells the environment the step limit, so that it
#: ends a truncated episode itself, with the episode metrics in its last info
STEP_LIMIT_SYNC = WrapperSpec("StepLimitSync", "srpb_gym.env:StepLimitSync", {})


def _max_steps(scenario: str) -> int:
    """Control steps in the scenario's time limit (at the default control step)."""
    data = yaml.safe_load((scenarios_dir() / f"{scenario}.yaml").read_text(encoding="utf-8"))
    return math.ceil(float(data.get("time_limit", 60.0)) / CONTROL_DT - 1e-9)


def register_envs() -> None:
    """Register every id (idempotent). ``SRPB-Custom-v0`` takes ``scenario="file.yaml"``
    and truncates at that file's time limit itself. ``SRPB-Mix-v0`` draws one of
    :data:`MIX_SCENARIOS` per reset (``scenarios=[...]``, ``weights=[...]`` change them);
    its step limit covers the longest of them, and each episode ends at its own
    scenario's time limit."""
    for env_id, scenario in SCENARIO_IDS.items():
        if env_id not in gym.registry:
            gym.register(env_id, entry_point=ENTRY_POINT, kwargs={"scenario": scenario},
                         max_episode_steps=_max_steps(scenario),
                         additional_wrappers=(STEP_LIMIT_SYNC,))  # fmt: skip
    if CUSTOM_ID not in gym.registry:
        gym.register(CUSTOM_ID, entry_point=ENTRY_POINT, additional_wrappers=(STEP_LIMIT_SYNC,))
    if MIX_ID not in gym.registry:
        gym.register(MIX_ID, entry_point=MIX_ENTRY_POINT,
                     max_episode_steps=max(_max_steps(s) for s in MIX_SCENARIOS),
                     additional_wrappers=(STEP_LIMIT_SYNC,))  # fmt: skip

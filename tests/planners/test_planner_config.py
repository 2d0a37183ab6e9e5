"""Planner settings: frozen config dataclasses built strictly from plain data, and read
from text (YAML files and NAME.FIELD=VALUE assignments)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from srpb_gym.errors import InputError
from srpb_gym.planners import (
    DWA,
    PLANNERS,
    DWAConfig,
    GlobalPlanner,
    GlobalPlannerConfig,
    GoToGoalConfig,
    RecoveryConfig,
    SocialDWA,
    SocialDWAConfig,
    SocialForcePlanner,
    SocialForcePlannerConfig,
    check_settings,
    make_planner,
    planner_config,
)
from srpb_gym.planners.config import (
    load_settings,
    merge_settings,
    parse_assignments,
    parse_value,
    planner_settings,
)
from srpb_gym.planners.recovery import Recovery

CONFIGS = [DWAConfig, SocialDWAConfig, SocialForcePlannerConfig, GoToGoalConfig,
           GlobalPlannerConfig, RecoveryConfig]  # fmt: skip


def test_every_planner_has_a_config() -> None:
    for name, cls in PLANNERS.items():
        planner = make_planner(name)
        assert isinstance(planner.config, cls.config_class), name
        assert planner_config(name) == planner.config


@pytest.mark.parametrize("cls", CONFIGS)
def test_configs_are_frozen(cls) -> None:
    config = cls()
    field = dataclasses.fields(config)[0].name
    with pytest.raises(dataclasses.FrozenInstanceError):
        setattr(config, field, 1.0)
    assert cls.from_spec(None) == config and cls.from_spec(config) is config


def test_defaults_of_the_parts() -> None:
    """Each planner's global planner and recovery keep the settings they always had."""
    assert GlobalPlanner().config == GlobalPlannerConfig()
    assert GlobalPlannerConfig().person_margin == 0.05
    assert DWA().planner.config == GlobalPlannerConfig(person_margin=0.1)
    social = SocialDWA().planner.config
    assert social == GlobalPlannerConfig(person_margin=0.1, heuristic_weight=1.5,
                                         replan_period=3.0, min_replan_interval=1.0)  # fmt: skip
    assert SocialForcePlanner().planner.config == GlobalPlannerConfig()
    for planner in (DWA(), SocialDWA(), SocialForcePlanner()):
        assert planner.planner.person_radius == planner.config.person_radius == 0.3
        assert planner.recovery.config == RecoveryConfig()


def test_mapping_changes_only_the_named_fields() -> None:
    planner = make_planner("social-dwa", {"w_psi": 1.0, "global_planner": {"spacing": 0.2}})
    assert planner.config.w_psi == 1.0 and planner.config.w_fsi == SocialDWAConfig().w_fsi
    gp = planner.planner.config
    assert gp.spacing == 0.2 and gp.heuristic_weight == 1.5 and gp.person_margin == 0.1
    dwa = DWA({"horizon": 3, "recovery": {"window": 4.0}})
    assert dwa.config.horizon == 3.0 and isinstance(dwa.config.horizon, float)
    assert dwa.recovery.config.window == 4.0 and dwa._steps == 30


@pytest.mark.parametrize(
    ("name", "settings", "expected"),
    [
        ("dwa", {"horizon": -1.0}, "planner.dwa.horizon: must be a finite number > 0, got -1.0"),
        ("dwa", {"horizon": float("nan")}, "planner.dwa.horizon: must be finite"),
        ("dwa", {"horizonn": 2.0}, "planner.dwa.horizonn: unknown key; valid keys: "),
        ("dwa", {"horizon": "long"}, "planner.dwa.horizon: expected a number, got 'long'"),
        ("dwa", {"n_v": 1}, "planner.dwa.n_v: must be an integer >= 2, got 1"),
        ("dwa", {"n_w": 2.5}, "planner.dwa.n_w: expected an integer"),
        ("dwa", {"w_path": -1}, "planner.dwa.w_path: must be a finite number >= 0"),
        ("dwa", {"global_planner": {"spacing": 0}}, "planner.dwa.global_planner.spacing: "),
        ("dwa", {"global_planner": {"oncoming_cos": 2}}, "planner.dwa.global_planner.oncoming_"),
        ("dwa", {"global_planner": 3}, "planner.dwa.global_planner: must be a GlobalPlannerConf"),
        ("dwa", {"recovery": {"window": 0}}, "planner.dwa.recovery.window: must be a finite"),
        ("dwa", [1, 2], "planner.dwa: expected a mapping of settings"),
        ("social-dwa", {"social_stride": 50}, "planner.social-dwa.social_stride: must not excee"),
        ("social-dwa", {"min_scale": 1.5}, "planner.social-dwa.min_scale: must be in [0.0, 1.0]"),
        ("social-force", {"v_pref": 0.0}, "planner.social-force.v_pref: must be a finite number"),
        ("social-force", {"anisotropy": -0.1}, "planner.social-force.anisotropy: must be in"),
        ("go-to-goal", {"k_turn": 0}, "planner.go-to-goal.k_turn: must be a finite number > 0"),
    ],
)
def test_bad_settings_name_the_dotted_key(name: str, settings, expected: str) -> None:
    with pytest.raises(InputError) as err:
        make_planner(name, settings)
    assert str(err.value).startswith(expected)


def test_direct_construction_checks_too() -> None:
    with pytest.raises(ValueError, match="horizon must be a finite number > 0"):
        DWAConfig(horizon=0.0)
    with pytest.raises(ValueError, match="backup_speed must be a finite number >= 0"):
        RecoveryConfig(backup_speed=-0.1)
    assert Recovery({"backup_time": 2.0}).config.backup_time == 2.0
    with pytest.raises(KeyError, match="unknown planner"):
        make_planner("teleport", {})
    with pytest.raises(InputError, match=r"planner\.teleport: unknown planner"):
        check_settings({"teleport": {}})


def test_values_from_text() -> None:
    assert parse_value("2.0") == 2.0 and parse_value("1e-3") == 0.001
    assert parse_value("3") == 3 and parse_value(" [1, 2] ") == [1, 2]
    assert parse_value("true") is True and parse_value("None") is None
    assert parse_value("null") is None and parse_value("{a: 1}") == {"a": 1}
    assert parse_value("fast") == "fast" and parse_value("__import__('os')") == "__import__('os')"


def test_assignments() -> None:
    items = ["dwa.horizon=2.5", "dwa.global_planner.spacing = 0.2", "social-dwa.w_psi=6"]
    assert parse_assignments(items) == {
        "dwa": {"horizon": 2.5, "global_planner": {"spacing": 0.2}},
        "social-dwa": {"w_psi": 6},
    }
    for bad in ("dwa.horizon", "horizon=2", "dwa..horizon=2", ".horizon=1"):
        with pytest.raises(InputError, match=r"--planner-param: expected PLANNER\.FIELD=VALUE"):
            parse_assignments([bad])
    with pytest.raises(InputError, match=r"dwa\.recovery is set to a value and to fields"):
        parse_assignments(["dwa.recovery=1", "dwa.recovery.window=2"])
    assert merge_settings({"a": {"b": 1, "c": 2}}, {"a": {"c": 3}}) == {"a": {"b": 1, "c": 3}}


def test_settings_file(tmp_path) -> None:
    path = tmp_path / "planners.yaml"
    path.write_text("dwa:\n  horizon: 2.5\n  global_planner:\n    spacing: 0.2\nsocial-dwa:\n")
    assert load_settings(path) == {"dwa": {"horizon": 2.5, "global_planner": {"spacing": 0.2}},
                                   "social-dwa": {}}  # fmt: skip
    settings = planner_settings(path, ["dwa.horizon=3.0", "dwa.n_v=5"])
    assert settings["dwa"] == {"horizon": 3.0, "global_planner": {"spacing": 0.2}, "n_v": 5}
    planner = make_planner("dwa", settings["dwa"])
    assert planner.config.n_v == 5 and planner.planner.config.spacing == 0.2
    (tmp_path / "empty.yaml").write_text("")
    assert load_settings(tmp_path / "empty.yaml") == {}
    for text, expected in (("- 1\n", "expected a mapping of planner names"),
                           ("dwa: 3\n", "dwa: expected a mapping of settings"),
                           ("dwa: [\n", "not valid YAML")):  # fmt: skip
        path.write_text(text)
        with pytest.raises(InputError, match=expected):
            load_settings(path)
    with pytest.raises(InputError, match="cannot read the file"):
        load_settings(tmp_path / "missing.yaml")


def test_docs_list_every_setting_with_its_default() -> None:
    doc = (Path(__file__).resolve().parents[2] / "docs" / "planners.md").read_text()
    inherited = {f.name for f in dataclasses.fields(DWAConfig)} - {"global_planner"}
    for cls in CONFIGS:
        section = doc.split(f"### `{cls.__name__}`")[1].split("\n### ")[0]
        config = cls()
        for field in dataclasses.fields(cls):
            if cls is SocialDWAConfig and field.name in inherited:
                continue
            value = getattr(config, field.name)
            shown = f"`{type(value).__name__}`" if dataclasses.is_dataclass(value) else f"`{value}`"
            assert f"| `{field.name}` | {shown}" in section, (cls.__name__, field.name)


def test_old_planner_settings_name_still_works():
    import srpb_gym.planners as planners

    with pytest.warns(DeprecationWarning, match="SocialForcePlannerConfig"):
        assert planners.SocialForceConfig is SocialForcePlannerConfig

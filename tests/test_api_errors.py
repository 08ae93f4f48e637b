"""Typed errors, never tracebacks, from the API and the CLI (issue 26, findings 4 and 5): Storm's
failures, the task wrapper's arguments, a labelling function that breaks its contract, and env
ids nested in a world file's env arguments."""

from __future__ import annotations

import json
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.errors import MitlcError
from mitlc.gym import TaskWrapper, TaskWrapperError, TaskWrapperTypeError, make_task_env
from mitlc.labels import LabelFunctionError
from mitlc.worlds import WorldError
from mitlc.worlds.door import load_env_task

PACKAGES = Path(__file__).parent / "packages"
runner = CliRunner()

ONE_CELL = """name: one-cell
grid: {rows: 1, cols: 1}
labels: {a: [[0, 0]]}
start: [0, 0]
actions: [stay]
motion: {intended: 1.0, spread: 0.0}
observation: {type: local-pattern}
spec: {formula: "F a"}
horizon: 3
"""
"""The fuzzer's world: a 1x1 POMDP grid whose one cell holds the task's goal."""


def one_cell(tmp_path: Path) -> Path:
    path = tmp_path / "one-cell.yaml"
    path.write_text(ONE_CELL, encoding="utf-8")
    return path


def check_json(*args: str) -> dict[str, Any]:
    result = runner.invoke(app, ["check", *args, "--json"])
    assert result.exit_code == 0, result.output
    assert "Traceback" not in result.output
    return dict(json.loads(result.output[result.output.index("{") :]))


# -- Storm --------------------------------------------------------------------------------------


def test_a_one_cell_pomdp_gets_its_bounds(tmp_path: Path) -> None:
    pytest.importorskip("stormpy.pomdp")
    report = check_json(str(one_cell(tmp_path)))
    assert report["pmax"] == 1.0
    assert report["bounds"]["lower"] == report["bounds"]["upper"] == 1.0


def test_the_exported_product_numbers_its_start_first(tmp_path: Path) -> None:
    """Storm checks a property for every state of the DRN (stormpy's default) without failing:
    the start state, which nothing reaches, is no longer numbered last."""
    stormpy = pytest.importorskip("stormpy")
    from mitlc.automata import translate
    from mitlc.check.drn import storm_property, to_drn
    from mitlc.product.explicit import build_product
    from mitlc.syntax import parse
    from mitlc.worlds import load_world

    world = load_world(one_cell(tmp_path))
    product = build_product(world, translate(parse(world.spec)))
    text = to_drn(product)
    assert "\nstate 0 init" in text
    path = tmp_path / "product.drn"
    path.write_text(text, encoding="utf-8")
    model = stormpy.build_model_from_drn(str(path))
    for prop in (storm_property(product), 'Pmax=? [(G !"satisfied") & (G F "acc0")]'):
        result = stormpy.model_checking(model, stormpy.parse_properties(prop)[0])
        assert len(result.get_value_vector()) == model.nr_states


STORM_CALLS = [
    ("stormpy", "build_model_from_drn"),
    ("stormpy", "parse_properties"),
    ("stormpy", "model_checking"),
    ("stormpy.environments", "sound"),
    ("stormpy.pomdp", "verify_with_belief_unfolding"),
    ("stormpy.pomdp", "verify_with_belief_discretization"),
]


@pytest.fixture
def failing_storm(request: pytest.FixtureRequest, monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """One of Storm's entry points made to fail as Storm does (a ``RuntimeError``)."""
    pytest.importorskip("stormpy.pomdp")
    import importlib

    module_name, name = request.param
    module = importlib.import_module(module_name)

    def fail(*args: Any, **kwargs: Any) -> Any:
        raise RuntimeError("IllegalArgumentException: Invalid item count (2) of state labeling")

    monkeypatch.setattr(module, name, fail)
    yield name


@pytest.mark.parametrize(
    "failing_storm", STORM_CALLS, indirect=True, ids=[n for _, n in STORM_CALLS]
)
def test_every_storm_failure_is_a_typed_error(tmp_path: Path, failing_storm: str) -> None:
    from mitlc.automata import translate
    from mitlc.check.pomdp import pomdp_bounds
    from mitlc.check.storm import StormError
    from mitlc.syntax import parse
    from mitlc.worlds import load_world

    world = load_world(one_cell(tmp_path))
    with pytest.raises(StormError, match=r"^Storm failed on .*: IllegalArgumentException") as err:
        pomdp_bounds(world, translate(parse(world.spec)))
    assert isinstance(err.value, MitlcError) and isinstance(err.value, ValueError)
    report = check_json(str(one_cell(tmp_path)))  # the exact values stand; the bounds say why not
    assert report["pmax"] == 1.0
    assert report["bounds"]["unavailable"].startswith("Storm failed on ")


def test_storms_log_is_restored_after_a_failure() -> None:
    developer = pytest.importorskip("stormpy.developer")
    from mitlc.check.storm import StormError, storm_guard

    before = developer.get_log_level()
    with pytest.raises(StormError, match="Storm failed on a test: boom"), storm_guard("a test"):
        assert developer.get_log_level() == developer.LogLevel.OFF
        raise RuntimeError("boom\nmore")
    assert developer.get_log_level() == before


# -- the task wrapper's arguments ----------------------------------------------------------------

LABELS = {"goal": {"obs": [15]}}


def frozen_lake() -> gym.Env[Any, Any]:
    return gym.make("FrozenLake-v1", max_episode_steps=20)


@pytest.mark.parametrize("spec", [None, 5, b"F goal", ["F goal"]])
def test_a_spec_that_is_no_formula_nor_automaton_is_a_type_error(spec: Any) -> None:
    with pytest.raises(TaskWrapperTypeError, match=r"^spec: expected a formula's text") as err:
        TaskWrapper(frozen_lake(), spec, LABELS, horizon=20)
    assert isinstance(err.value, TypeError) and isinstance(err.value, MitlcError)


BAD_ARGUMENTS: list[tuple[dict[str, Any], type[Exception], str]] = [
    ({"horizon": "5"}, TypeError, "horizon: expected a positive integer, got '5'"),
    ({"horizon": 0}, ValueError, "horizon: expected a positive integer, got 0"),
    ({"rewards": 5}, TypeError, "rewards: expected a mapping of reward terms"),
    ({"rewards": {"move": "x"}}, TypeError, "rewards.move: expected a number"),
    ({"rewards": {"bonus": 1}}, ValueError, "rewards: unknown term 'bonus'"),
    ({"flatten": "yes"}, TypeError, "flatten: expected True or False"),
    ({"max_automaton_states": "3"}, TypeError, "max_automaton_states: expected a positive"),
    ({"max_jumps": -1}, ValueError, "max_jumps: expected an integer >= 0"),
    ({"env_key": 3}, TypeError, "env_key: expected a non-empty string"),
    ({"env_key": "clocks"}, ValueError, "env_key: 'clocks' is the name of the task's part"),
    ({"env_end": None}, TypeError, "env_end: expected 'auto' or 'step' or 'finish'"),
    ({"task_obs": "clock"}, ValueError, "task_obs: expected 'state' or 'clocks'"),
    ({"reward_mode": 1}, TypeError, "reward_mode: expected 'replace' or 'add'"),
    ({"potential": "1"}, TypeError, "potential: expected a reach >= 0"),
    ({"potential": -1.0}, ValueError, "potential: expected a reach >= 0"),
]


@pytest.mark.parametrize(("kwargs", "kind", "message"), BAD_ARGUMENTS)
def test_each_wrong_argument_is_named_when_the_wrapper_is_made(
    kwargs: dict[str, Any], kind: type[Exception], message: str
) -> None:
    with pytest.raises(TaskWrapperError) as err:
        TaskWrapper(frozen_lake(), "F goal", LABELS, **{"horizon": 20, **kwargs})
    assert isinstance(err.value, kind) and str(err.value).startswith(message)


def test_an_env_or_labels_of_the_wrong_kind_is_a_type_error() -> None:
    with pytest.raises(TaskWrapperTypeError, match=r"^env: expected a gymnasium.Env, got NoneType"):
        TaskWrapper(None, "F goal", LABELS, horizon=20)  # type: ignore[arg-type]
    with pytest.raises(TaskWrapperTypeError, match=r"^labels: expected a mapping .* got int"):
        TaskWrapper(frozen_lake(), "F goal", 5, horizon=20)  # type: ignore[arg-type]


def test_gymnasium_make_of_the_task_id_checks_the_same_arguments() -> None:
    import mitlc.gym  # noqa: F401  (registers mitlc/Task-v0)

    with pytest.raises(TaskWrapperTypeError, match=r"^spec: "):
        gym.make("mitlc/Task-v0", env_id="FrozenLake-v1", spec=None, labels=LABELS, horizon=5)
    with pytest.raises(TaskWrapperTypeError, match=r"^horizon: "):
        make_task_env(env_id="FrozenLake-v1", spec="F goal", labels=LABELS, horizon=2.5)  # type: ignore[arg-type]


# -- a labelling function --------------------------------------------------------------------

CONTRACT = r"takes \(obs, info\) and returns the set of true propositions"


@pytest.mark.parametrize(
    "function",
    [lambda obs: {"goal"}, lambda obs, info, extra: {"goal"}, lambda: set()],
    ids=["one-argument", "three-arguments", "none"],
)
def test_a_labelling_function_that_cannot_take_obs_and_info_fails_at_construction(
    function: Any,
) -> None:
    with pytest.raises(
        LabelFunctionError, match=f"cannot be called as f\\(obs, info\\).*{CONTRACT}"
    ):
        TaskWrapper(frozen_lake(), "F goal", function, horizon=20)


@pytest.mark.parametrize(
    ("result", "shown"),
    [(None, "returned None"), (5, "returned 5"), ("goal", "returned 'goal'"), ([1], "with 1")],
)
def test_a_labelling_function_that_returns_no_names_fails_at_reset(result: Any, shown: str) -> None:
    env = TaskWrapper(frozen_lake(), "F goal", lambda obs, info: result, horizon=20)
    with pytest.raises(LabelFunctionError, match=f"{shown}.*{CONTRACT}") as err:
        env.reset(seed=0)
    assert isinstance(err.value, TypeError) and isinstance(err.value, MitlcError)


def test_a_labelling_function_that_breaks_its_contract_later_is_still_a_typed_error() -> None:
    calls: list[int] = []

    def labels(obs: Any, info: dict[str, Any]) -> Any:
        calls.append(obs)
        return ["goal"] if len(calls) < 3 else None

    env = TaskWrapper(frozen_lake(), "F goal", labels, horizon=20)
    env.reset(seed=0)
    with pytest.raises(LabelFunctionError, match="returned None"):
        env.step(0)


def test_a_labelling_function_of_any_iterable_of_names_works() -> None:
    env = TaskWrapper(frozen_lake(), "F goal", lambda obs, info: ["goal"], horizon=20)
    env.reset(seed=0)
    assert env.step(0)[4]["verdict"] == "satisfied"


# -- env ids nested in a world file's env arguments ---------------------------------------------

ALIAS = "MitlcTestAlias/Task-v0"
"""An id a package might register on mitlc's task entry point (``mitlc/Task-v0`` itself is
refused in a world file)."""


@pytest.fixture
def alias(monkeypatch: pytest.MonkeyPatch) -> Iterator[str]:
    """The alias registered, and the test package importable by name."""
    import mitlc.gym  # noqa: F401  (registers mitlc/Task-v0, as in the fuzzer's process)

    monkeypatch.syspath_prepend(str(PACKAGES))
    monkeypatch.setitem(gym.registry, ALIAS, gym.registry["mitlc/Task-v0"])
    yield ALIAS


def nested_world(tmp_path: Path, env_id: str, outer: str = ALIAS, extra: str = "") -> Path:
    path = tmp_path / "world.yaml"
    path.write_text(
        f"""name: nested
env:
  id: {outer}
  kwargs:
    env_id: {json.dumps(env_id)}
    spec: "F goal"
    labels: {{goal: {{obs: [15]}}}}
    horizon: 10{extra}
labels: {{goal: {{info: verdict, equals: satisfied}}}}
spec: {{formula: "F goal"}}
horizon: 10
""",
        encoding="utf-8",
    )
    return path


NESTED_REFUSED = [
    ("/tmp/evil.py:FrozenLake-v1", "5:13: env.kwargs.env_id: '/tmp/evil.py' is not a module's "
     "dotted name"),
    ("no_such_module_x:FrozenLake-v1", "5:13: env.kwargs.env_id: no installed module "
     "'no_such_module_x'"),
    ("mitlc/Task-v0", "5:13: env.kwargs.env_id: mitlc/Task-v0 is mitlc's own"),
    ("GymV26Environment-v0", "env.kwargs.env_id: GymV26Environment-v0 makes another environment"),
    ("NoSuchEnv-v0", "5:13: env.kwargs.env_id: no gymnasium environment 'NoSuchEnv-v0'"),
]  # fmt: skip


@pytest.mark.parametrize(("env_id", "message"), NESTED_REFUSED)
def test_a_nested_env_id_is_checked_as_the_outer_one(
    tmp_path: Path, alias: str, env_id: str, message: str
) -> None:
    modules = set(sys.modules)
    with pytest.raises(WorldError) as err:
        load_env_task(nested_world(tmp_path, env_id))
    assert message in str(err.value)
    assert not {m for m in set(sys.modules) - modules if "evil" in m or "no_such" in m}
    result = runner.invoke(app, ["check", str(tmp_path / "world.yaml")])
    assert result.exit_code == 1 and "Traceback" not in result.output
    assert message in result.output and len(result.output.strip().splitlines()) == 1


def test_a_nested_module_is_imported_by_name_as_an_outer_one(
    tmp_path: Path, alias: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.delitem(sys.modules, "mitlc_test_envs", raising=False)
    monkeypatch.delitem(gym.registry, "MitlcTest/Probe-v0", raising=False)
    extra = "\n    env_kwargs: {size: 4}"
    world = nested_world(tmp_path, "mitlc_test_envs:MitlcTest/Probe-v0", extra=extra)
    world.write_text(world.read_text().replace("obs: [15]", "obs: [3]"))
    task = load_env_task(world)
    assert task.propositions == ("goal",)
    assert "mitlc_test_envs" in sys.modules and "MitlcTest/Probe-v0" in gym.registry
    deeper = f"\n    env_kwargs: {{env_id: '{alias}', env_kwargs: {{env_id: 'x/y.py:Foo-v0'}}}}"
    with pytest.raises(WorldError, match=r"env\.kwargs\.env_kwargs\.env_kwargs\.env_id: 'x/y\.py'"):
        load_env_task(nested_world(tmp_path, alias, extra=deeper))


def test_an_own_outer_id_is_refused_before_anything_is_imported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.syspath_prepend(str(PACKAGES))
    monkeypatch.delitem(sys.modules, "mitlc_test_envs", raising=False)
    path = nested_world(tmp_path, "FrozenLake-v1", outer="mitlc/Task-v0")
    path.write_text(path.read_text().replace("env:\n", "env:\n  import: [mitlc_test_envs]\n"))
    with pytest.raises(WorldError, match=r"env.id: mitlc/Task-v0 is mitlc's own"):
        load_env_task(path)
    assert "mitlc_test_envs" not in sys.modules

"""The trust model (issue 42): a world file written by someone else reads and writes no file
outside its folder and the run directory, and runs no code but the import of the installed
packages it names and their registered envs (:mod:`mitlc.worlds.trust`). Each attack is a
hostile world file in ``tmp_path``, refused with one line naming its field; the command line
runs a set of them and no file appears outside the run directory, no traceback is printed."""

from __future__ import annotations

import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import gymnasium as gym
import pytest
from typer.testing import CliRunner

from mitlc.cli import app
from mitlc.labels import compile_labels
from mitlc.labels.probe import attr_problems
from mitlc.labels.values import MISSING, attribute, step_into
from mitlc.worlds import WorldError
from mitlc.worlds.door import load_env_task
from mitlc.worlds.load import load_world
from mitlc.worlds.trust import path_key, path_text, trusting

PACKAGES = Path(__file__).parent / "packages"
ROOT = Path(__file__).parent.parent
GRID = "grid: {rows: 1, cols: 2}\nlabels: {a: [[0, 1]]}\nstart: [0, 0]\n" \
       "motion: {intended: 1.0, sideways: 0.0}\nhorizon: 5\n"  # fmt: skip
BOX = "{a: {box: {index: [0], low: [0.5], high: [3]}}}"


def env_world(folder: Path, env: str, labels: str = BOX, name: str = "world.yaml") -> Path:
    """An env world file in ``folder`` (``env`` and ``labels`` as YAML flow text)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / name
    path.write_text(f"env: {env}\nlabels: {labels}\nspec: {{formula: 'F[0,5] a'}}\nhorizon: 10\n")
    return path


def refused(path: Path, load: Any = load_env_task) -> str:
    """The one-line message refusing the world file at ``path``."""
    with pytest.raises(WorldError) as err:
        load(path)
    text = str(err.value)
    assert len(text.splitlines()) == 1, text
    return text


@pytest.fixture
def package(monkeypatch: pytest.MonkeyPatch) -> Any:
    """The test package, importable by name as an installed one is."""
    monkeypatch.syspath_prepend(str(PACKAGES))
    import mitlc_test_envs

    return mitlc_test_envs


# -- spec: files inside the world's folder ------------------------------------------------------


@pytest.mark.parametrize("spec", ["/etc/passwd", "../../../../../../etc/hostname", "~/x.mitl"])
def test_a_spec_file_outside_the_folder_is_named_not_read(tmp_path: Path, spec: str) -> None:
    path = tmp_path / "w" / "world.yaml"
    path.parent.mkdir()
    path.write_text(GRID + f"spec: {spec}\n")
    text = refused(path, load_world)
    assert "world.yaml:6:7: spec: the spec file" in text and spec in text and "refused" in text
    assert "root:x" not in text and "parse" not in text


def test_a_symlink_out_of_the_folder_is_refused(tmp_path: Path) -> None:
    secret = tmp_path / "secret.mitl"
    secret.write_text("F a\n")
    (tmp_path / "w").mkdir()
    (tmp_path / "w" / "task.mitl").symlink_to(secret)
    path = tmp_path / "w" / "world.yaml"
    path.write_text(GRID + "spec: task.mitl\n")
    assert "symlink" in refused(path, load_world)


def test_a_spec_file_below_the_folder_is_read(tmp_path: Path) -> None:
    (tmp_path / "tasks").mkdir()
    (tmp_path / "tasks" / "task.mitl").write_text("F[0,3] a\n")
    path = tmp_path / "world.yaml"
    path.write_text(GRID + "spec: tasks/../tasks/task.mitl\n")
    assert load_world(path).spec == "F[0,3] a\n"


# -- arguments and wrappers -----------------------------------------------------------------------


@pytest.mark.parametrize(
    ("env", "message"),
    [
        ("{id: CartPole-v1, wrappers: [{class: 'stable_baselines3.common.monitor:Monitor', "
         "kwargs: {filename: OUT}}]}",
         ": env.wrappers[0].class: stable_baselines3.common.monitor is neither "
         "gymnasium.wrappers nor a package the file names"),
        ("{import: [mitlc_test_envs], id: CartPole-v1, wrappers: [{class: "
         "'mitlc_test_envs:Recorder', kwargs: {filename: OUT}}]}",
         "env.wrappers[0].kwargs.filename: an argument that names a file (filename)"),
        ("{id: CartPole-v1, wrappers: [{class: "
         "'gymnasium.wrappers:RecordVideo', kwargs: {video_folder: OUT}}]}",
         "env.wrappers[0].kwargs.video_folder: an argument that names a file"),
        ("{id: Ant-v5, kwargs: {xml_file: OUT.xml}}",
         "env.kwargs.xml_file: an argument that names a file (xml_file)"),
        ("{id: CartPole-v1, kwargs: {config: {where: [OUT]}}}",
         "env.kwargs.config.where[0]: "),
        ("{id: CartPole-v1, kwargs: {config: {'OUT': 1}}}",
         "an argument that names a file (/"),
        ("{id: CartPole-v1, kwargs: {sutton_barto_reward: 'evilmod:Thing'}}",
         "env.kwargs.sutton_barto_reward: 'evilmod:Thing' reads as a file's path or a "
         "module:name"),
    ],
)  # fmt: skip
def test_wrappers_and_arguments_that_reach_outside_are_refused(
    tmp_path: Path, env: str, message: str
) -> None:
    target = tmp_path / "outside" / "PWNED"
    path = env_world(tmp_path / "w", env.replace("OUT", str(target)))
    text = refused(path)
    assert message in text and "--trust-world" in text
    assert not target.parent.exists()


def test_trusted_a_world_may_name_files_and_any_wrapper(tmp_path: Path, package: Any) -> None:
    wrapper = "{class: 'mitlc_test_envs:Recorder', kwargs: {tag: 'a/b'}}"
    path = env_world(tmp_path, f"{{id: MitlcTest/Probe-v0, wrappers: [{wrapper}]}}",
                     "{a: {attr: speed, above: 0.5}}")  # fmt: skip
    assert "mitlc_test_envs is neither gymnasium.wrappers" in refused(path)
    path = env_world(tmp_path, f"{{import: [mitlc_test_envs], id: MitlcTest/Probe-v0, "
                     f"wrappers: [{wrapper}]}}", "{a: {attr: speed, above: 0.5}}")  # fmt: skip
    assert "env.wrappers[0].kwargs.tag: 'a/b' reads as a file's path" in refused(path)
    with trusting():
        assert load_env_task(path).propositions == ("a",)
    assert "'a/b' reads as" in refused(path)  # the trust was for that block only


def test_what_reads_as_a_path() -> None:
    assert all(map(path_key, ["xml_file", "video_folder", "filename", "log_dir", "savePath"]))
    assert not any(map(path_key, ["map_name", "max_steps", "is_slippery", "render_mode"]))
    assert all(path_text(t) for t in ["a/b", "..", "~", "x.csv", "C:\\x", "mod:Name"])
    assert not any(path_text(t) for t in ["8x8", "human", "1.5", "rgb_array", "key"])
    assert not path_text("ALE/Pong-v5", {"ALE/Pong-v5"})  # a registered env id


# -- modules only from the installed packages ---------------------------------------------------

EVIL = "import pathlib\npathlib.Path({!r}).write_text('ran')\n"


@pytest.mark.parametrize("env", ["{id: 'evilmod:Foo-v0'}", "{import: [evilmod], id: CartPole-v1}",
                                 "{import: [evilpkg.sub], id: CartPole-v1}"])  # fmt: skip
def test_a_module_in_the_current_directory_is_not_imported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, env: str
) -> None:
    ran = tmp_path / "RAN"
    (tmp_path / "evilmod.py").write_text(EVIL.format(str(ran)))
    (tmp_path / "evilpkg").mkdir()
    (tmp_path / "evilpkg" / "__init__.py").write_text(EVIL.format(str(ran)))
    (tmp_path / "evilpkg" / "sub.py").write_text(EVIL.format(str(ran)))
    monkeypatch.chdir(tmp_path)
    monkeypatch.syspath_prepend("")  # as python -c and the interactive prompt do
    path = env_world(tmp_path / "w", env)
    text = refused(path)
    assert "is a file in the current directory, not an installed package" in text
    assert ": env.i" in text and not ran.exists()
    assert "evilmod" not in sys.modules and "evilpkg" not in sys.modules


def test_a_module_in_the_worlds_folder_is_not_imported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    ran = tmp_path / "RAN"
    folder = tmp_path / "w"
    folder.mkdir()
    (folder / "evilmod2.py").write_text(EVIL.format(str(ran)))
    monkeypatch.syspath_prepend(str(folder))
    monkeypatch.chdir(ROOT)
    text = refused(env_world(folder, "{import: [evilmod2], id: CartPole-v1}"))
    assert "env.import[0]: module 'evilmod2' is a file in the world's folder" in text
    assert not ran.exists()


def test_a_package_installed_below_the_current_directory_is_imported(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A virtual environment inside a project: its site-packages is a sys.path entry below
    the current directory."""
    site = tmp_path / "venv" / "site-packages"
    site.mkdir(parents=True)
    (site / "mitlc_installed_here.py").write_text("IMPORTED = True\n")
    monkeypatch.syspath_prepend(str(site))
    monkeypatch.chdir(tmp_path)
    monkeypatch.delitem(sys.modules, "mitlc_installed_here", raising=False)
    load_env_task(env_world(tmp_path / "w", "{import: [mitlc_installed_here], id: CartPole-v1}"))
    assert "mitlc_installed_here" in sys.modules


@pytest.mark.parametrize(
    "start", [["-m", "mitlc"], ["-c", "import sys; from mitlc.cli import main; main()"]]
)
def test_however_mitlc_is_started_the_current_directory_is_not_imported_from(
    tmp_path: Path, start: list[str]
) -> None:
    """``python -m mitlc`` (the current directory taken off ``sys.path``) and ``python -c``
    (``''`` left on it: the module's origin is refused)."""
    ran = tmp_path / "RAN"
    (tmp_path / "evilmod.py").write_text(EVIL.format(str(ran)))
    env_world(tmp_path, "{id: 'evilmod:Foo-v0'}")
    done = subprocess.run([sys.executable, *start, "train", "world.yaml", "--out", "run"],
                          cwd=tmp_path, capture_output=True, text=True, timeout=120,
                          env={**os.environ, "PYTHONPATH": str(ROOT)})  # fmt: skip
    assert done.returncode == 1 and "Traceback" not in done.stderr, done.stderr
    assert "world.yaml:1:11: env.id: " in done.stderr and not ran.exists()
    assert len(done.stderr.strip().splitlines()) == 1, done.stderr


# -- attr: reads data, never code ---------------------------------------------------------------


@pytest.mark.parametrize(
    ("attr", "message"),
    [
        ("np_random.bit_generator.cffi", "env.unwrapped.np_random is a property of CartPoleEnv"),
        ("action_space.np_random", "env.unwrapped.action_space.np_random is a property"),
        ("step", "env.unwrapped.step is a method of CartPoleEnv"),
        ("spec.pprint", "env.unwrapped.spec.pprint is a method of EnvSpec"),
    ],
)
def test_an_attr_path_through_code_is_refused_at_its_line(
    tmp_path: Path, attr: str, message: str
) -> None:
    path = env_world(tmp_path, "{id: CartPole-v1}", f"{{a: {{attr: '{attr}'}}}}")
    text = refused(path)
    assert text.startswith(f"{path}:2:20: labels.a.attr: ") and message in text, text


def test_a_dunder_is_refused_when_the_file_is_read(tmp_path: Path) -> None:
    text = refused(env_world(tmp_path, "{id: CartPole-v1}", "{a: {attr: '__class__'}}"))
    assert "labels.a.attr: '__class__' is not a public attribute name" in text


def test_reading_a_property_does_not_run_it() -> None:
    space = gym.spaces.Discrete(3)
    assert step_into(space, "np_random", True) is MISSING
    assert space._np_random is None  # not seeded by the read
    assert step_into(space, "n", True) == 3


@dataclass
class Pose:
    x: float
    y: float


@dataclass(slots=True)
class Slotted:
    pose: Pose


class Data:
    """Plain data: instance attributes, a slots dataclass, a class attribute, a container."""

    kind = "robot"

    def __init__(self) -> None:
        self.where = Slotted(Pose(1.0, 2.0))
        self.items = [{"name": "key"}]

    @property
    def computed(self) -> int:
        raise AssertionError("a property was run")


def test_data_is_read_code_is_not() -> None:
    env = Data()
    assert step_into(step_into(step_into(env, "where", True), "pose", True), "x", True) == 1.0
    assert attribute(env, "kind") == "robot" and step_into(env, "items", True)[0]["name"] == "key"
    assert step_into(env, "computed", True) is MISSING
    assert attribute(env, "computed").kind == "property"


class Exploding:
    def __array__(self, *args: object, **kwargs: object) -> Any:
        raise RuntimeError("boom\nsecond line")

    def __repr__(self) -> str:
        raise RuntimeError("boom")


def test_an_error_while_reading_is_one_line() -> None:
    env = Data()
    env.bad = Exploding()  # type: ignore[attr-defined]
    labeller = compile_labels({"a": {"attr": "bad", "box": {"low": [0], "high": [1]}}})
    [problem] = attr_problems(labeller, env)
    assert problem == "labels.a.attr: reading env.unwrapped.bad failed (RuntimeError: boom)"


def test_data_attributes_of_an_env_are_read(tmp_path: Path) -> None:
    labels = "{a: {attr: spec.id, equals: CartPole-v1}, b: {attr: metadata.render_fps}}"
    path = env_world(tmp_path, "{id: CartPole-v1}", labels)
    path.write_text(path.read_text().replace("F[0,5] a", "F[0,5] (a & b)"))
    assert load_env_task(path).propositions == ("a", "b")


@pytest.mark.parametrize("name", ["minigrid-doorkey.yaml", "minigrid-empty.yaml", "highway.yaml"])
def test_the_shipped_examples_read_data(name: str) -> None:
    """MiniGrid's and highway-env's attributes, as the shipped files name them, are data."""
    pytest.importorskip("minigrid" if name.startswith("minigrid") else "highway_env")
    assert load_env_task(ROOT / "specs" / "envs" / name).propositions


# -- the command line: a set of hostile files, nothing written outside the run ------------------


def snapshot(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*")} if folder.exists() else set()


def test_hostile_world_files_write_nothing_outside_the_run(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Each hostile file run through ``mitlc train`` and ``mitlc check`` from a working
    directory in ``tmp_path``: exit 1, one line per problem naming its field, no traceback,
    and no file anywhere but in the run directory (which stays empty)."""
    work, outside = tmp_path / "work", tmp_path / "outside"
    work.mkdir()
    outside.mkdir()
    (outside / "keep.txt").write_text("x")
    (work / "evilmod.py").write_text(EVIL.format(str(outside / "RAN")))
    target = str(outside / "PWNED")
    monitor = "{class: 'stable_baselines3.common.monitor:Monitor', kwargs: {filename: OUT}}"
    monitor = monitor.replace("OUT", target)
    hostile = {
        "monitor": (f"{{import: [stable_baselines3], id: CartPole-v1, wrappers: [{monitor}]}}", BOX,
                    "env.wrappers[0].kwargs.filename"),
        "video": (f"{{id: CartPole-v1, kwargs: {{render_mode: rgb_array}}, wrappers: [{{class: "
                  f"'gymnasium.wrappers:RecordVideo', kwargs: {{video_folder: {target}}}}}]}}", BOX,
                  "env.wrappers[0].kwargs.video_folder"),
        "xml": (f"{{id: Ant-v5, kwargs: {{xml_file: {target}.xml}}}}", BOX, "env.kwargs.xml_file"),
        "module": ("{id: 'evilmod:Foo-v0'}", BOX, "env.id"),
        "rng": ("{id: CartPole-v1}", "{a: {attr: np_random.bit_generator.cffi}}", "labels.a.attr"),
    }  # fmt: skip
    for name, (env, labels, _) in hostile.items():
        env_world(work, env, labels, f"{name}.yaml")
    (work / "spec.yaml").write_text(GRID + "spec: /etc/passwd\n")
    hostile["spec"] = ("", "", "spec")
    monkeypatch.chdir(work)
    monkeypatch.syspath_prepend("")
    before = snapshot(tmp_path)
    runner = CliRunner()
    for name, (_, _, field) in hostile.items():
        for command in (["train", f"{name}.yaml", "--out", "run", "-q"], ["check", f"{name}.yaml"]):
            result = runner.invoke(app, command)
            assert result.exit_code == 1, (command, result.output)
            assert isinstance(result.exception, SystemExit), (command, result.exception)
            assert "Traceback" not in result.output and "root:" not in result.output
            lines = result.output.strip().splitlines()
            at = "env.id" if (name, command[0]) == ("rng", "check") else field  # not finite
            assert len(lines) == 1 and f": {at}" in lines[0], (command, result.output)
    new = snapshot(tmp_path) - before
    assert all(p == work / "run" or p.is_relative_to(work / "run") for p in new), sorted(new)
    assert snapshot(outside) == {outside / "keep.txt"} and "evilmod" not in sys.modules


@pytest.mark.parametrize("command", ["check", "train", "eval", "plot"])
def test_the_commands_that_load_worlds_take_trust_world(command: str) -> None:
    result = CliRunner().invoke(app, [command, "--help"], terminal_width=200)
    assert "--trust-world" in result.output


def trusting_world(tmp_path: Path) -> Path:
    """A world whose wrapper takes an argument that reads as a path (harmless here)."""
    wrapper = "{class: 'mitlc_test_envs:Recorder', kwargs: {tag: 'a/b'}}"
    return env_world(tmp_path, f"{{import: [mitlc_test_envs], id: MitlcTest/Probe-v0, "
                     f"wrappers: [{wrapper}]}}", "{a: {attr: speed, above: 0.5}}")  # fmt: skip


def test_trust_world_on_the_command_line_is_for_that_command(tmp_path: Path, package: Any) -> None:
    path = str(trusting_world(tmp_path))
    runner = CliRunner()
    for trust in ([], ["--trust-world"], []):
        result = runner.invoke(app, ["check", path, *trust])
        assert result.exit_code == 1 and len(result.output.strip().splitlines()) == 1
        refused = "'a/b' reads as a file's path" in result.output
        assert refused == (not trust), result.output  # trusted: made, then not finite


@pytest.mark.slow
def test_a_trusted_world_trains(
    tmp_path: Path, package: Any, monkeypatch: pytest.MonkeyPatch
) -> None:
    trusting_world(tmp_path)
    monkeypatch.chdir(tmp_path)
    runner = CliRunner()
    train = ["train", "world.yaml", "--episodes", "1", "--no-eval", "-q"]
    refused = runner.invoke(app, [*train, "--out", "run1"])
    assert refused.exit_code == 1 and "'a/b' reads as a file's path" in refused.output
    trusted = runner.invoke(app, [*train, "--out", "run2", "--trust-world"])
    assert trusted.exit_code == 0, trusted.output

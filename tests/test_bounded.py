"""Bounded work (issue 11): linear translation, the time limit, the state limit and the
product-size limit, each ending in one line that names the limit and how to raise it."""

from __future__ import annotations

import random
import time
from collections.abc import Hashable, Mapping
from itertools import product as cartesian
from pathlib import Path

import pytest
from typer.testing import CliRunner

from mitlc.automata import StateLimitError, TranslationError, compile_formula, translate
from mitlc.automata.guards import Box, partition
from mitlc.automata.ldba import translate_terms
from mitlc.automata.progress import Progression
from mitlc.automata.terms import SEQUENTIAL_CUBES
from mitlc.automata.text import atom_text, form_ast, form_text
from mitlc.check import check
from mitlc.check.observed import observed_bound
from mitlc.check.solve import pmax_horizon
from mitlc.cli import app
from mitlc.limits import Deadline, LimitError
from mitlc.product.explicit import ProductSizeError, build_product, estimate
from mitlc.syntax import parse, to_text
from mitlc.worlds import load_world
from tests.conftest import ROOT
from tests.strategies import random_formula

runner = CliRunner()
CASE1 = ROOT / "specs" / "paper" / "case1.yaml"
CASE2 = ROOT / "specs" / "paper" / "case2.yaml"
EXPLOSIVE = "F[0,1000] G[0,1000] a"


def _expired(what: str = "test") -> Deadline:
    deadline = Deadline(1e-6, what)
    time.sleep(0.002)
    return deadline


def _one_line_error(output: str, *needles: str) -> None:
    lines = output.strip().splitlines()
    assert len(lines) == 1, output
    assert "Traceback" not in output
    for needle in needles:
        assert needle in lines[0], output


# --- linear translation ------------------------------------------------------------------------


@pytest.mark.parametrize("k", [10**3, 10**4, 10**5])
def test_bounded_eventually_has_k_plus_3_states(k: int) -> None:
    # F[0,k] a owes F[0,j] a for j = k down to 0 (F[0,0] a is kept as a state, for folding),
    # plus the violated and the satisfied sink: k + 3 states, so states (and time) grow linearly.
    digital = translate(parse(f"F[0,{k}] a"))
    assert len(digital.states) == k + 3
    assert sum(s.verdict == "pending" for s in digital.states) == k + 1


@pytest.mark.parametrize("k", [10**3, 10**4])
def test_bounded_eventually_folds_into_three_locations(k: int) -> None:
    compiled = compile_formula(parse(f"F[0,{k}] a"))
    assert len(compiled.timed.locations) == 3
    assert compiled.timed.clock_bounds == (k,)


def test_large_disjunctions_substitute_as_one_at_a_time() -> None:
    # F[0,40] G[20,40] a owes up to 20 windows at once, none implying another (subsumption
    # drops the windows that another implies: F[0,n] G[0,n] a owes one); its progression
    # takes the union of the cubes at once, and must give the form that or-ing them one at a
    # time gives.
    translation = translate_terms(parse("F[0,40] G[20,40] a"))
    assert len(translation.automaton.states) == 673
    store = translation.store
    progression = Progression(store)
    large = [f for f, cubes in enumerate(store.forms) if len(cubes) > SEQUENTIAL_CUBES]
    assert len(large) > 100
    for form in large[:: len(large) // 40]:
        for letter in (0, 1):

            def step(atom: int, letter: int = letter) -> int:
                return progression.step(store.atom_form(atom), letter)

            at_once = store.substitute(form, step)
            one_by_one = store._substitute_sequential(store.forms[form], step)
            assert at_once == one_by_one == progression.step(form, letter)


def test_response_family_grows_linearly() -> None:
    sizes = [len(translate(parse(f"G(a -> F[0,{k}] b)")).states) for k in (100, 1000)]
    assert sizes == [102, 1002]


# --- the time limit ------------------------------------------------------------------------------


def test_deadline_basics() -> None:
    never = Deadline.none()
    for _ in range(1000):
        never.check()
    never.check_now()
    assert never.unlimited and never.remaining() is None
    assert Deadline(0, "x").unlimited  # 0 is no limit, as --time-limit 0
    deadline = _expired("mitlc compile").at("translation")
    assert deadline.remaining() == 0.0
    with pytest.raises(LimitError) as err:
        deadline.check_now()
    assert str(err.value) == (
        "mitlc compile stopped at the time limit of 1e-06 s (during translation); raise it "
        "with --time-limit SECONDS (0 for none)"
    )
    counted = _expired()
    counted.every = 3
    counted.check()
    counted.check()
    with pytest.raises(LimitError):
        counted.check()  # the third call reads the clock


def test_translation_stops_at_the_time_limit() -> None:
    start = time.monotonic()
    with pytest.raises(LimitError, match=r"time limit of 0\.3 s.*time_limit argument"):
        translate(parse(EXPLOSIVE), time_limit=0.3)
    assert time.monotonic() - start < 5


def test_many_recurrences_stop_at_the_time_limit() -> None:
    # 2^17 candidate jumps from the initial state, nearly all of them empty: the enumeration of
    # epsilon jumps reads the clock too (it ran for minutes past --time-limit before).
    formula = parse("G F a & " + "G F " * 16 + "b")
    with pytest.raises(LimitError, match=r"time limit of 0\.5 s"):
        translate(formula, time_limit=0.5)


def test_compile_stops_at_the_time_limit_through_the_cli() -> None:
    result = runner.invoke(app, ["compile", "-e", EXPLOSIVE, "--time-limit", "0.3"])
    assert result.exit_code == 1
    _one_line_error(
        result.output,
        "mitlc compile stopped at the time limit of 0.3 s (during translation)",
        "raise it with --time-limit SECONDS (0 for none)",
    )


def test_render_and_monitor_take_the_time_limit(tmp_path: Path) -> None:
    out = tmp_path / "a.dot"
    render = runner.invoke(app, ["render", "-e", EXPLOSIVE, "-o", str(out), "--time-limit", "0.2"])
    assert render.exit_code == 1
    _one_line_error(render.output, "mitlc render stopped at the time limit of 0.2 s")
    spec, trace = tmp_path / "task.mitl", tmp_path / "trace.csv"
    spec.write_text(EXPLOSIVE + "\n", encoding="utf-8")
    trace.write_text("a\n1\n0\n", encoding="utf-8")
    monitor = runner.invoke(app, ["monitor", str(spec), str(trace), "--time-limit", "0.2"])
    assert monitor.exit_code == 1
    _one_line_error(monitor.output, "mitlc monitor stopped at the time limit of 0.2 s")
    bad = runner.invoke(app, ["compile", "-e", "a", "--time-limit", "-1"])
    assert bad.exit_code == 2


def test_no_time_limit_compiles() -> None:
    result = runner.invoke(app, ["compile", "-e", "F[0,50] a", "--time-limit", "0"])
    assert result.exit_code == 0 and '"format": "mitlc.tldgba/1"' in result.output


def test_every_check_stage_reads_the_deadline() -> None:
    world = load_world(CASE1)
    automaton = translate(parse(world.spec, world.spec_source))
    with pytest.raises(LimitError, match=r"\(during the product build\)"):
        build_product(world, automaton, deadline=_expired())
    product = build_product(world, automaton)
    with pytest.raises(LimitError, match="test stopped at the time limit"):
        check(world, automaton, deadline=_expired())
    with pytest.raises(LimitError):
        pmax_horizon(product, 30, deadline=_expired())
    noisy = load_world(CASE2)
    noisy_product = build_product(noisy, translate(parse(noisy.spec, noisy.spec_source)))
    with pytest.raises(LimitError):
        observed_bound(noisy, noisy_product, deadline=_expired())


def test_check_stops_at_the_time_limit_through_the_cli() -> None:
    result = runner.invoke(app, ["check", str(CASE1), "--time-limit", "0.000001"])
    assert result.exit_code == 1
    _one_line_error(result.output, "mitlc check stopped at the time limit of 1e-06 s")


def test_a_horizon_past_the_fixpoint_costs_nothing() -> None:
    # `horizon: 1000000000`: once a step changes nothing, the steps left are not computed.
    world = load_world(CASE1)
    product = build_product(world, translate(parse(world.spec, world.spec_source)))
    within, _ = pmax_horizon(product, 200, keep_history=False)
    start = time.monotonic()
    forever, kept = pmax_horizon(product, 10**9, keep_history=False, time_limit=10)
    assert forever == within and len(kept) == 1
    assert time.monotonic() - start < 5
    short, history = pmax_horizon(product, 80)
    assert len(history) == 81 and short == within
    assert (history[-1] == history[-2]).all()
    # With the history kept, the steps past the fixpoint share one read-only table.
    _, long_history = pmax_horizon(product, 10**6)
    assert len(long_history) == 10**6 + 1
    assert len({id(table) for table in long_history}) < 200
    assert not long_history[-1].flags.writeable
    assert (long_history[-1] == history[-1]).all()


# --- the state limit ------------------------------------------------------------------------------


def test_state_limit_says_how_to_raise_it() -> None:
    with pytest.raises(StateLimitError) as err:
        compile_formula(parse("G (a -> F[5,10] b)"), max_states=50)
    assert isinstance(err.value, LimitError) and isinstance(err.value, TranslationError)
    message = str(err.value)
    assert "\n" not in message
    assert "--max-states 50" in message and "raise the state limit" in message
    result = runner.invoke(app, ["compile", "-e", "G (a -> F[5,10] b)", "--max-states", "50"])
    assert result.exit_code == 1
    _one_line_error(result.output, "--max-states 50", "larger --max-states")


# --- the product's size ---------------------------------------------------------------------------


def test_product_estimate_bounds_the_product() -> None:
    plain = load_world(CASE1)
    for spec in (plain.spec, "G F a & G F b", "F G a", "G (a -> F[0,3] b)"):
        world = load_world(CASE1, spec)
        automaton = translate(parse(spec))
        built = build_product(world, automaton)
        states, transitions = estimate(world, automaton)
        assert built.num_states <= states
        assert built.num_transitions <= transitions


def test_product_size_refusal() -> None:
    """The limit counts the product's states as they are built: the eager automaton's bound
    (every world state with every automaton state) refuses nothing by itself."""
    world = load_world(CASE1)
    automaton = translate(parse(world.spec, world.spec_source))
    states = build_product(world, automaton).num_states
    assert estimate(world, automaton)[0] > states  # the bound is above the product
    build_product(world, automaton, max_product_states=states)  # at the limit: built
    with pytest.raises(ProductSizeError) as err:
        build_product(world, automaton, max_product_states=states - 1)
    assert isinstance(err.value, LimitError)
    assert f"past the limit of {states - 1:,} states" in str(err.value)
    result = runner.invoke(app, ["check", str(CASE1), "--max-product-states", "100"])
    assert result.exit_code == 1
    _one_line_error(result.output, "past the limit of 100 states", "--max-product-states N")


# --- guards: the breakpoint partition against the value-by-value one it replaced ------------------


def _reference_partition(
    points: Mapping[tuple[int, ...], Hashable], dims: int, bound: int, above: Hashable | None
) -> list[tuple[Box, Hashable]]:
    """The partition as it was before the breakpoints (mitlc 0.1.0's, verbatim): every value of
    ``[0, bound]`` in turn, and a linear scan for the nearest value present."""
    if not points:
        return []
    if dims == 0:
        ((_, behaviour),) = points.items()
        return [((), behaviour)]
    groups: dict[int, dict[tuple[int, ...], Hashable]] = {}
    for valuation, behaviour in points.items():
        groups.setdefault(valuation[0], {})[valuation[1:]] = behaviour
    present = sorted(groups)
    signature = {x: tuple(_reference_partition(groups[x], dims - 1, bound, above)) for x in present}
    beyond = None if above is None else tuple(_full(dims - 1, bound, above))

    def behaviour_at(x: int) -> tuple[tuple[Box, Hashable], ...]:
        if beyond is not None and x > present[-1]:
            return beyond
        return signature[_nearest(present, x)]

    result: list[tuple[Box, Hashable]] = []
    start, current = 0, behaviour_at(0)
    for x in range(1, bound + 1):
        here = behaviour_at(x)
        if here != current:
            result.extend(_prefixed(start, x - 1, current))
            start, current = x, here
    result.extend(_prefixed(start, bound, current))
    return result


def _full(dims: int, bound: int, behaviour: Hashable) -> list[tuple[Box, Hashable]]:
    return [(tuple((0, bound) for _ in range(dims)), behaviour)]


def _nearest(present: list[int], x: int) -> int:
    below = [p for p in present if p <= x]
    return below[-1] if below else present[0]


def _prefixed(
    lo: int, hi: int, rest: tuple[tuple[Box, Hashable], ...]
) -> list[tuple[Box, Hashable]]:
    return [(((lo, hi), *box), behaviour) for box, behaviour in rest]


def test_partition_matches_the_value_by_value_reference() -> None:
    rng = random.Random(11)
    for _ in range(3000):
        dims, bound = rng.randint(0, 3), rng.randint(0, 7)
        every = list(cartesian(range(bound + 2), repeat=dims))  # values past bound too
        chosen = rng.sample(every, rng.randint(1, min(len(every), 12)))
        points = {v: rng.choice("xyz") for v in chosen}
        above = rng.choice([None, "sink", "x"])
        assert partition(points, dims, bound, above) == _reference_partition(
            points, dims, bound, above
        ), (points, dims, bound, above)


# --- obligation text: printed directly, as the printer prints the formula -------------------------


def test_form_text_is_the_printers_text() -> None:
    rng = random.Random(5)
    checked = 0
    for _ in range(150):
        formula = random_formula(rng, rng.randint(1, 3), ("a", "b", "c"), rng.random() < 0.5, 6)
        try:
            store = translate_terms(formula, max_states=300).store
        except TranslationError:
            continue
        for form in range(len(store.forms)):
            assert form_text(store, form) == to_text(form_ast(store, form))
            checked += 1
        for atom in range(len(store.atoms)):
            assert atom_text(store, atom) == to_text(form_ast(store, store.atom_form(atom)))
    assert checked > 1000

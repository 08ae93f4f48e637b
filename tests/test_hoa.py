"""HOA output and Boolean labels: hand-built digital automata read back by Spot, and the
two-level minimisation of letter sets checked against its definition on seeded random sets."""

from __future__ import annotations

import itertools
import random

import networkx as nx
import pytest

from mitlc.automata.digital import DigitalAutomaton, DigitalState
from mitlc.automata.hoa import to_hoa, to_hoa_stream
from mitlc.automata.labels import Cube, label_text, minimal_cover, prime_implicants
from mitlc.semantics import holds_finite
from mitlc.syntax import parse

spot = pytest.importorskip("spot")

Word = tuple[tuple[int, ...], tuple[int, ...]]
"""A lasso of letter indices: prefix, loop (non-empty)."""


def _state(obligation: str, component: str = "accepting", verdict: str = "pending") -> DigitalState:
    return DigitalState(obligation, component, verdict)  # type: ignore[arg-type]


def gf_a() -> DigitalAutomaton:
    """``G F a``: one state, the ``a`` edge in set 0."""
    return DigitalAutomaton.from_table(
        "G F a", "G F a", ("a",), (_state("G F a"),), 0, ((0, 0),), ((0, 1),), 1
    )


def fg_a() -> DigitalAutomaton:
    """``F G a``: wait in 0, jump to 1 (``G a``, ``a`` marked), ``!a`` there falls in sink 2."""
    states = (
        _state("F G a", "initial"),
        _state("G a"),
        _state("false", verdict="violated"),
    )
    delta = ((0, 0), (2, 1), (2, 2))
    marks = ((0, 0), (0, 1), (0, 0))
    return DigitalAutomaton.from_table(
        "F G a", "F G a", ("a",), states, 0, delta, marks, 1, ((0, 1),)
    )


def g_a() -> DigitalAutomaton:
    """``G a`` with zero acceptance sets: ``!a`` leads to the violated sink 1."""
    states = (_state("G a"), _state("false", verdict="violated"))
    return DigitalAutomaton.from_table(
        "G a", "G a", ("a",), states, 0, ((1, 0), (1, 1)), ((0, 0), (0, 0)), 0
    )


def f_g_safe() -> DigitalAutomaton:
    """``F G a`` again but with zero sets: state 0 loops (every infinite run accepts), so the
    jump makes an accepting SCC nondeterministic; the language is ``true``."""
    states = (_state("true", "initial"), _state("G a"), _state("false", verdict="violated"))
    delta = ((0, 0), (2, 1), (2, 2))
    marks = ((0, 0), (0, 0), (0, 0))
    return DigitalAutomaton.from_table("x", "x", ("a",), states, 0, delta, marks, 0, ((0, 1),))


def gf_a_gf_b() -> DigitalAutomaton:
    """``G F a & G F b``: one state; letter bit 0 (a) is set 0, bit 1 (b) is set 1."""
    return DigitalAutomaton.from_table(
        "G F a & G F b",
        "G F a & G F b",
        ("a", "b"),
        (_state("G F a & G F b"),),
        0,
        ((0, 0, 0, 0),),
        ((0, 1, 2, 3),),
        2,
    )


ALL = {"gf_a": gf_a, "fg_a": fg_a, "g_a": g_a, "f_g_safe": f_g_safe, "gf_a_gf_b": gf_a_gf_b}


def accepts(aut: DigitalAutomaton, word: Word) -> bool:
    """Acceptance of a lasso by the digital automaton, from its definition: some reachable cycle
    of the product with the lasso, avoiding violated states, sees every acceptance set."""
    prefix, loop = word
    letters = prefix + loop
    nxt = [i + 1 if i + 1 < len(letters) else len(prefix) for i in range(len(letters))]
    graph: nx.DiGraph = nx.DiGraph()
    for s, i in itertools.product(range(len(aut.states)), range(len(letters))):
        if aut.states[s].verdict == "violated":
            continue
        graph.add_node((s, i))
        t = aut.delta[s][letters[i]]
        if aut.states[t].verdict != "violated":
            graph.add_edge((s, i), (t, nxt[i]), marks=aut.marks[s][letters[i]])
        for target in aut.jumps_from(s):
            graph.add_edge((s, i), (target, i), marks=0)
    if (aut.initial, 0) not in graph:
        return False
    reach = nx.descendants(graph, (aut.initial, 0)) | {(aut.initial, 0)}
    for scc in nx.strongly_connected_components(graph.subgraph(reach)):
        inner = [d["marks"] for u, v, d in graph.subgraph(scc).edges(data=True)]
        union = 0
        for m in inner:
            union |= m
        if inner and union & aut.all_sets == aut.all_sets:
            return True
    return False


def word_text(aut: DigitalAutomaton, word: Word) -> str:
    """The lasso in Spot's word syntax, each letter a full conjunction of literals."""

    def letter(m: int) -> str:
        lits = [p if m >> i & 1 else "!" + p for i, p in enumerate(aut.propositions)]
        return " & ".join(lits) or "true"

    prefix, loop = word
    return "".join(letter(m) + "; " for m in prefix) + "cycle{" + "; ".join(map(letter, loop)) + "}"


def spot_accepts(parsed: object, aut: DigitalAutomaton, word: Word) -> bool:
    """Whether Spot's reading of the HOA accepts the lasso."""
    w = spot.parse_word(word_text(aut, word), parsed.get_dict())  # type: ignore[attr-defined]
    return bool(parsed.intersects(w.as_automaton()))  # type: ignore[attr-defined]


def all_words(num_letters: int, max_prefix: int, max_loop: int) -> list[Word]:
    """Every lasso with prefix up to ``max_prefix`` and loop of 1 .. ``max_loop`` letters."""
    words: list[Word] = []
    for p, q in itertools.product(range(max_prefix + 1), range(1, max_loop + 1)):
        for prefix in itertools.product(range(num_letters), repeat=p):
            for loop in itertools.product(range(num_letters), repeat=q):
                words.append((prefix, loop))
    return words


@pytest.mark.parametrize("name", sorted(ALL))
def test_spot_reads_the_hoa_with_the_same_language(name: str) -> None:
    aut = ALL[name]()
    text = to_hoa(aut)
    assert text == to_hoa(aut), "output must be canonical"
    parsed = spot.automaton(text)
    assert parsed.num_states() == len(aut.states)
    assert parsed.num_sets() == aut.num_sets
    assert [str(p) for p in parsed.ap()] == list(aut.propositions)
    for word in all_words(aut.num_letters, 2, 3):
        assert spot_accepts(parsed, aut, word) == accepts(aut, word), word_text(aut, word)


@pytest.mark.parametrize("name", sorted(ALL))
def test_claimed_properties_hold(name: str) -> None:
    aut = ALL[name]()
    text = to_hoa(aut)
    claims = next(line for line in text.splitlines() if line.startswith("properties:")).split()
    parsed = spot.automaton(text)
    for prop in ("universal", "semi_deterministic", "complete"):
        getattr(parsed, "prop_" + prop)(spot.trival.maybe())  # forget the trusted claims
    assert spot.is_deterministic(parsed) == ("deterministic" in claims)
    if "semi-deterministic" in claims:
        assert spot.is_semi_deterministic(parsed)
    if not aut.epsilon:
        assert "semi-deterministic" not in claims
    assert spot.is_complete(parsed) == ("complete" in claims)


def test_semi_deterministic_is_claimed_only_when_true() -> None:
    assert "semi-deterministic" in to_hoa(fg_a())
    assert "semi-deterministic" not in to_hoa(f_g_safe())


def test_gf_a_text() -> None:
    assert to_hoa(gf_a()) == (
        'HOA: v1\nname: "G F a"\nStates: 1\nStart: 0\nAP: 1 "a"\nacc-name: Buchi\n'
        "Acceptance: 1 Inf(0)\n"
        "properties: trans-labels explicit-labels trans-acc complete deterministic\n"
        "--BODY--\nState: 0\n[!0] 0\n[0] 0 {0}\n--END--\n"
    )


def test_zero_sets_violated_state_is_dead() -> None:
    text = to_hoa(g_a())
    assert "Acceptance: 0 t" in text and "acc-name: all" in text
    assert text.endswith("State: 0\n[0] 0\n[!0] 1\nState: 1\n--END--\n")


def test_header_details() -> None:
    text = to_hoa(gf_a_gf_b(), name='say "hi" \\ there')
    assert 'name: "say \\"hi\\" \\\\ there"' in text
    assert "acc-name: generalized-Buchi 2\nAcceptance: 2 Inf(0)&Inf(1)\n" in text
    assert spot.automaton(text).get_name() == 'say "hi" \\ there'


def test_stream() -> None:
    auts = [gf_a(), fg_a(), g_a()]
    text = to_hoa_stream(auts)
    assert text.count("--END--") == 3
    parsed = list(spot.automata(text))
    assert [p.num_states() for p in parsed] == [len(a.states) for a in auts]


# --- labels ---------------------------------------------------------------------------------------


def random_sets(seed: int, count: int, max_props: int) -> list[tuple[int, set[int]]]:
    rng = random.Random(seed)
    sets = []
    for _ in range(count):
        n = rng.randint(0, max_props)
        density = rng.random()
        sets.append((n, {m for m in range(1 << n) if rng.random() < density}))
    return sets


def covered(cubes: list[Cube], n: int) -> set[int]:
    return {m for cube in cubes for m in cube.letters(n)}


@pytest.mark.parametrize("seed", range(4))
def test_cover_is_exact_prime_and_canonical(seed: int) -> None:
    for n, letters in random_sets(seed, 100, 8):
        cover = minimal_cover(letters, n)
        assert covered(cover, n) == letters
        primes = set(prime_implicants(letters, n))
        assert all(cube in primes for cube in cover)
        shuffled = sorted(letters, key=lambda m: (m * 7919) % 257)
        assert minimal_cover(shuffled, n) == cover
        assert len(set(cover)) == len(cover)


def test_primes_are_prime() -> None:
    for n, letters in random_sets(7, 100, 6):
        for cube in prime_implicants(letters, n):
            assert set(cube.letters(n)) <= letters
            for i in range(n):
                if cube.care >> i & 1:
                    bigger = Cube(cube.care & ~(1 << i), cube.value & ~(1 << i))
                    assert not set(bigger.letters(n)) <= letters


def test_cover_is_minimum_on_small_sets() -> None:
    for n, letters in random_sets(11, 200, 3):
        cover = minimal_cover(letters, n)
        primes = prime_implicants(letters, n)
        for k in range(len(cover)):
            for combo in itertools.combinations(primes, k):
                assert covered(list(combo), n) != letters


def test_constant_and_simple_labels() -> None:
    assert label_text([], ("a", "b")) == "false"
    assert label_text([], ("a", "b"), "hoa") == "f"
    assert label_text(range(4), ("a", "b")) == "true"
    assert label_text([0], (), "hoa") == "t"
    assert label_text([1, 3, 4, 5, 7], ("a", "b", "c")) == "a | !b & c"
    assert label_text([1, 3, 4, 5, 7], ("a", "b", "c"), "hoa") == "0 | !1&2"
    assert label_text([1, 2], ("a", "b")) == "a & !b | !a & b"


@pytest.mark.parametrize("seed", range(2))
def test_spec_label_parses_to_the_same_letters(seed: int) -> None:
    props = ("a", "b", "c", "d")
    for n, letters in random_sets(seed + 100, 60, 4):
        names = props[:n]
        formula = parse(label_text(letters, names))
        for m in range(1 << n):
            letter = frozenset(p for i, p in enumerate(names) if m >> i & 1)
            assert holds_finite(formula, (letter,)) == (m in letters)


def test_many_propositions_fall_back_correctly() -> None:
    rng = random.Random(3)
    letters = {rng.randrange(1 << 14) for _ in range(40)}
    assert covered(minimal_cover(letters, 14), 14) == letters
    assert minimal_cover(range(1, 1 << 11, 2), 11) == [Cube(1, 1)]  # just "a"
    with pytest.raises(ValueError):
        minimal_cover([4], 2)

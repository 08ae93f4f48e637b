"""Random strings drawn from the grammar's own rules, fast and seeded.

``hypothesis.extra.lark`` does the same with shrinking but draws about three strings a second
from this grammar; this walker draws thousands, so the round-trip property sees volume.
"""

from __future__ import annotations

import random
import re
from collections import defaultdict
from functools import cache

from lark.grammar import NonTerminal, Rule, Symbol, Terminal

from mitlc.syntax.grammar import build_parser

BUILT = build_parser()
"""The parser built from the grammar (with its grammar object, which a loaded one lacks)."""

# Every spelling the grammar accepts for each terminal (checked against the terminal's regex).
SPELLINGS: dict[str, tuple[str, ...]] = {
    "IFF": ("<->", "<=>", "↔"),
    "IMPLIES": ("->", "=>", "→"),
    "OR": ("|", "||", "∨", "\\/"),
    "AND": ("&", "&&", "∧", "/\\"),
    "NOT": ("!", "¬", "~"),
    "NEXT": ("X", "○"),
    "EVENTUALLY": ("F", "◇"),
    "ALWAYS": ("G", "□"),
    "UNTIL": ("U",),
    "RELEASE": ("R",),
    "TRUE": ("true", "1", "⊤"),
    "FALSE": ("false", "0", "⊥"),
    "ATOM": ("a", "b", "req", "x1", "trueish", "f", "room_2"),
    "LPAR": ("(",),
    "RPAR": (")",),
    "LSQB": ("[", "_["),
    "LOPEN": ("(", "_("),
    "RSQB": ("]",),
    "SEP": (",", "..", ":"),
    "INT": tuple(str(n) for n in (0, 1, 2, 3, 5, 7, 10, 15, 20, 40)),
    "INF": ("inf", "infty", "∞"),
}
SEPARATORS = (" ", " ", " ", " ", "", "\n", "\t", "  # note\n")
# What may follow a spelling whose terminal has a look-ahead (`(` opens an interval only
# before a bound and a separator).
FOLLOW = {"LOPEN": "3,4]"}
VALID_INTERVAL_SHARE = 0.85
SHORTEST_SHARE = 0.3  # how often a nonterminal takes its shortest expansion, to keep strings short


@cache
def rules_by_origin() -> dict[str, tuple[Rule, ...]]:
    table: dict[str, list[Rule]] = defaultdict(list)
    for rule in BUILT.rules:
        table[rule.origin.name].append(rule)
    return {name: tuple(rules) for name, rules in table.items()}


@cache
def height(name: str) -> int:
    """The fewest expansions from nonterminal ``name`` down to terminals."""
    best = 10**6
    for rule in rules_by_origin()[name]:
        best = min(best, 1 + max((_symbol_height(s) for s in rule.expansion), default=0))
        # recursion through the same rule is cut by @cache returning a finite bound later
    return best


def _symbol_height(symbol: Symbol) -> int:
    if isinstance(symbol, Terminal):
        return 0
    if symbol.name in _IN_PROGRESS:
        return 10**6
    _IN_PROGRESS.add(symbol.name)
    try:
        return height(symbol.name)
    finally:
        _IN_PROGRESS.discard(symbol.name)


_IN_PROGRESS: set[str] = set()


def random_text(rng: random.Random, depth: int = 16) -> str:
    """One string of the language of the grammar (up to lexing and the interval checks)."""
    tokens: list[str] = []
    _expand(NonTerminal("start"), depth, rng, tokens)
    return "".join(token + rng.choice(SEPARATORS) for token in tokens)


def _expand(symbol: Symbol, depth: int, rng: random.Random, out: list[str]) -> None:
    if isinstance(symbol, Terminal):
        out.append(rng.choice(SPELLINGS[symbol.name]))
        return
    if symbol.name == "interval" and rng.random() < VALID_INTERVAL_SHARE:
        out.extend(_valid_interval(rng))
        return
    rules = rules_by_origin()[symbol.name]
    if depth <= 0 or rng.random() < SHORTEST_SHARE:
        lowest = min(_rule_height(r) for r in rules)
        rules = tuple(r for r in rules if _rule_height(r) == lowest)
    for child in rng.choice(rules).expansion:
        _expand(child, depth - 1, rng, out)


def _valid_interval(rng: random.Random) -> list[str]:
    """The tokens of an interval that passes the interval checks (most drawn ones should)."""
    lo = rng.randrange(0, 30)
    opener = rng.choice(SPELLINGS["LSQB"] + SPELLINGS["LOPEN"])
    closer = rng.choice(("]", ")"))
    if rng.random() < 0.3:
        return [opener, str(lo), rng.choice(SPELLINGS["SEP"]), rng.choice(SPELLINGS["INF"]), closer]
    hi = lo + rng.randrange(2, 30)
    return [opener, str(lo), rng.choice(SPELLINGS["SEP"]), str(hi), closer]


def _rule_height(rule: Rule) -> int:
    return max((_symbol_height(s) for s in rule.expansion), default=0)


def check_spellings() -> None:
    """Every terminal of the grammar has spellings, and each spelling matches its terminal."""
    for terminal in BUILT.terminals:
        if terminal.name in ("WS", "COMMENT"):
            continue
        assert terminal.name in SPELLINGS, f"no spellings for terminal {terminal.name}"
        pattern = re.compile(terminal.pattern.to_regexp())
        for spelling in SPELLINGS[terminal.name]:
            match = pattern.match(spelling + FOLLOW.get(terminal.name, " "))
            assert match is not None and match.end() == len(spelling), (terminal.name, spelling)

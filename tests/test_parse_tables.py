"""The stored LALR tables (``grammars/mitl.lalr.json``) are the grammar's: their stamp is the
grammar's, and the parser loaded from them parses (and fails) as the one built from the grammar.
``pytest --update-golden`` rewrites them after a change of the grammar or of Lark."""

from __future__ import annotations

import json
import random
from pathlib import Path

import lark
import pytest

from mitlc.syntax import grammar, to_text
from tests.conftest import ROOT
from tests.strategies import random_formula

TABLES = ROOT / "grammars" / grammar.TABLES_NAME


def _stored() -> lark.Lark:
    stored = json.loads(TABLES.read_text(encoding="utf-8"), object_hook=grammar._decode)
    parser: lark.Lark = lark.Lark._load_from_dict(stored["data"], stored["memo"])
    return parser


def test_the_stored_tables_are_stamped_with_this_grammar(update_golden: bool) -> None:
    if update_golden:
        TABLES.write_text(grammar.tables_text(grammar.build_parser()), encoding="utf-8")
    stored = json.loads(TABLES.read_text(encoding="utf-8"))
    assert stored["stamp"] == grammar._stamp(grammar.grammar_text()), (
        f"{TABLES.name} is stale: run pytest --update-golden and read the diff"
    )


def _corpus() -> list[str]:
    texts = [p.read_text(encoding="utf-8") for p in sorted((ROOT / "specs").rglob("*.mitl"))]
    texts += [
        line.strip()
        for line in (ROOT / "bench" / "formulas.txt").read_text(encoding="utf-8").splitlines()
        if line.strip() and not line.startswith("#")
    ]
    rng = random.Random(8)
    texts += [
        to_text(random_formula(rng, 4, ("a", "b", "c"), bounded=rng.random() < 0.5, max_bound=9))
        for _ in range(100)
    ]
    texts += ["a U", "(a", "F[3,1] a", "a && || b", "G[0,", "X", "a -> -> b", "", "¬a ∧ ◇[1..2] b"]
    return texts


def _outcome(parser: lark.Lark, text: str) -> object:
    try:
        return parser.parse(text)
    except lark.exceptions.UnexpectedInput as err:
        return (type(err).__name__, err.line, err.column, sorted(getattr(err, "expected", [])))


def test_the_stored_parser_parses_as_the_built_one() -> None:
    built, stored = grammar.build_parser(), _stored()
    for text in _corpus():
        assert _outcome(stored, text) == _outcome(built, text), text


def test_the_parser_in_use_is_the_stored_one_when_stamped(monkeypatch: pytest.MonkeyPatch) -> None:
    grammar.lalr_parser.cache_clear()
    called: list[bool] = []
    monkeypatch.setattr(grammar, "build_parser", lambda: called.append(True))
    try:
        assert isinstance(grammar.lalr_parser(), lark.Lark)
        assert not called
    finally:
        grammar.lalr_parser.cache_clear()


def test_stale_tables_are_not_used(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    stale = json.loads(TABLES.read_text(encoding="utf-8"))
    stale["stamp"] = "0" * 64
    (tmp_path / grammar.TABLES_NAME).write_text(json.dumps(stale), encoding="utf-8")
    (tmp_path / grammar.GRAMMAR_NAME).write_text(grammar.grammar_text(), encoding="utf-8")
    monkeypatch.setattr(grammar, "grammar_path", lambda: tmp_path / grammar.GRAMMAR_NAME)
    built: list[lark.Lark] = []
    real = grammar.build_parser
    monkeypatch.setattr(grammar, "build_parser", lambda: built.append(real()) or built[-1])
    grammar.lalr_parser.cache_clear()
    try:
        assert grammar.lalr_parser() is built[0]  # built from the grammar, not loaded
    finally:
        grammar.lalr_parser.cache_clear()

"""Hash-consed normal forms of MITL formulas: the states of the digital automaton.

A formula in normal form is a disjunction of cubes, a cube a conjunction of *atoms*, and an atom
a literal or a temporal operator whose operands are themselves normal forms (DNF all the way
down). Atoms and forms are interned, so equal formulas have equal integer ids; this is what
makes the progression of :mod:`mitlc.automata.progress` reach a finite set of states.

Temporal atoms keep the interval of the operator. ``X p`` is ``F[1,1] p``; an operator with an
interval ``[lo, inf)`` and ``lo > 0`` is rewritten once at normalisation (``F[lo,inf) p`` is
``F[lo,lo] F p``), so every unbounded operator has the interval ``[0, inf)`` and stays as it is
under progression: the unbounded atoms of every state are subformulas of the input.

Simplification keeps forms small and canonical enough: contradictory literals empty a cube,
a cube that contains another is dropped (absorption), within a cube an atom implied by
another atom with the same operator and operands is dropped (two pending ``F[0,k] b`` keep the
tighter one: ``G[0,x] p & G[0,y] p`` is ``G[0,max] p``), and, dually, in a disjunction a cube
that implies another cube is dropped (*subsumption*: ``F[0,x] p | F[0,y] p`` is
``F[0,max] p``, ``G[0,x] p | G[0,y] p`` is ``G[0,min] p``, the same for ``U``/``R`` with a
common left side). A cube implies another when each atom of the other is implied by one of its
atoms, by the interval rules of :meth:`TermStore.implies` (the syntactic subsumption of
MTL-to-automata translations, e.g. Maler, Nickovic and Pnueli, "From MITL to timed automata",
FORMATS 2006, and of LTL translators' formula reductions, Somenzi and Bloem, CAV 2000). Without
it, a state holding several pending ``F[0,k] b`` of different ages keeps every subset of their
deadlines (``F[0,k] (a & F[0,k] b)``: ``3 * 2^k`` states); with it, only the latest deadline
(``O(k^2)``).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import TypeAlias

INF = -1
"""The upper bound of an unbounded interval, in atoms."""

SEQUENTIAL_CUBES = 16
"""Forms of at most this many cubes are substituted one cube at a time (see
:meth:`TermStore.substitute`)."""

# Atom kinds.
LIT, EVENTUALLY, ALWAYS, UNTIL, RELEASE = "lit", "F", "G", "U", "R"

_HOLD_AT_END = frozenset({ALWAYS, RELEASE})
"""The atom kinds that hold at the end of a trace (:meth:`TermStore.end_value`)."""

Atom: TypeAlias = tuple[str, int, int, int, int]
"""``(kind, a, b, c, d)``: ``("lit", prop, positive, 0, 0)``, ``("F"|"G", lo, hi, operand, 0)``,
``("U"|"R", lo, hi, left, right)``; operands are form ids, ``hi == INF`` for unbounded."""

Cube: TypeAlias = frozenset[int]
Form: TypeAlias = frozenset[Cube]


class TermStore:
    """Interns atoms and forms; builds conjunctions and disjunctions in normal form."""

    def __init__(self, propositions: Iterable[str]) -> None:
        self.propositions: tuple[str, ...] = tuple(propositions)
        self.atoms: list[Atom] = []
        self._atom_ids: dict[Atom, int] = {}
        self.forms: list[Form] = []
        self._form_ids: dict[Form, int] = {}
        self.false = self.form(frozenset())
        self.true = self.form(frozenset({frozenset()}))
        self._and_cache: dict[tuple[int, int], int] = {}
        self._or_cache: dict[tuple[int, int], int] = {}
        self._ends: dict[int, bool] = {}
        self.texts: dict[int, tuple[str, int]] = {}
        """Memo of :func:`mitlc.automata.text.form_text`: a form's text and printer level."""

    # --- interning ------------------------------------------------------------------------------

    def atom(self, atom: Atom) -> int:
        """The id of ``atom``."""
        found = self._atom_ids.get(atom)
        if found is None:
            found = len(self.atoms)
            self.atoms.append(atom)
            self._atom_ids[atom] = found
        return found

    def form(self, cubes: Form) -> int:
        """The id of a form given as its set of cubes (assumed already simplified)."""
        found = self._form_ids.get(cubes)
        if found is None:
            found = len(self.forms)
            self.forms.append(cubes)
            self._form_ids[cubes] = found
        return found

    def atom_form(self, atom_id: int) -> int:
        """The form made of the single atom ``atom_id``."""
        return self.form(frozenset({frozenset({atom_id})}))

    # --- constructors ---------------------------------------------------------------------------

    def literal(self, prop: int, positive: bool) -> int:
        """The form of the literal ``p`` or ``!p``."""
        return self.atom_form(self.atom((LIT, prop, int(positive), 0, 0)))

    def temporal(
        self, kind: str, lo: int, hi: int, left: int, right: int = 0, keep_point: bool = False
    ) -> int:
        """The form of a temporal operator, with the trivial cases folded away.

        For ``F``/``G`` the operand is ``left``; for ``U``/``R`` the operands are ``left`` and
        ``right``. ``[0,0]`` is the (right) operand itself; ``true U_I q`` is ``F_I q`` and
        ``false R_I q`` is ``G_I q``; constants fold where that holds on finite traces too
        (``F_I false`` and ``G_I true``; from ``lo = 0``, ``F_I true`` and ``G_I false``; a later
        window of a constant is a point, ``F[2,4] true`` is ``F[2,2] true``: at least three
        letters); ``F[a,a]`` is a strong delay and ``G[a,a]`` a weak one (:meth:`delay`);
        ``F F p`` is ``F p`` and ``G G p`` is ``G p``. With ``keep_point`` an operator on
        ``[0,0]`` stays an atom: progression keeps it, so that folding can follow a bounded
        obligation to its last step (``!a U[0,0] a`` is the last step of ``!a U[5,10] a``).
        """
        if kind == UNTIL and left == self.true:
            kind, left = EVENTUALLY, right
        elif kind == RELEASE and left == self.false:
            kind, left = ALWAYS, right
        operand = left if kind in (EVENTUALLY, ALWAYS) else right
        if lo == 0 and hi == 0 and not keep_point:
            return operand
        if operand in (self.true, self.false):
            # F_I false = U_I false = false, G_I true = R_I true = true; from lo = 0 (the
            # current letter exists), F_I true = U_I true = true and G_I false = R_I false =
            # false. A later window of a constant owes letters: a point of it.
            strong = kind in (EVENTUALLY, UNTIL)
            if strong == (operand == self.false):
                return operand
            if lo == 0 and keep_point:  # kept by progression: the letter may not exist
                return self.point(EVENTUALLY if strong else ALWAYS, operand)
            if lo == 0:
                return operand
            if kind in (EVENTUALLY, ALWAYS):
                return self.delay(lo, operand, strong=kind == EVENTUALLY)
        if kind in (EVENTUALLY, ALWAYS):
            if lo == hi and lo > 0:
                return self.delay(lo, operand, strong=kind == EVENTUALLY)
            if hi == INF and self.is_unbounded(operand, kind):
                return operand
            return self.atom_form(self.atom((kind, lo, hi, operand, 0)))
        return self.atom_form(self.atom((kind, lo, hi, left, right)))

    def is_unbounded(self, form: int, kind: str) -> bool:
        """Whether ``form`` is the single unbounded atom ``F p`` (``G p``) for ``kind`` F (G)."""
        cubes = self.forms[form]
        if len(cubes) != 1:
            return False
        (cube,) = cubes
        if len(cube) != 1:
            return False
        (only,) = cube
        k, lo, hi, _, _ = self.atoms[only]
        return k == kind and lo == 0 and hi == INF

    def delay(self, steps: int, operand: int, strong: bool = True) -> int:
        """``operand`` ``steps`` letters later: strong, ``X^steps operand`` written
        ``F[steps,steps] operand`` (the letter must exist), or weak, ``G[steps,steps] operand``
        (it holds when the trace ends first), as LTLf's next and weak next (De Giacomo and
        Vardi, IJCAI 2013).

        Delays add up, and a delayed bounded window of the same strength shifts its interval:
        ``X^s F[l,h] p`` is ``F[l+s,h+s] p`` and a weak ``X^s G[l,h] p`` is ``G[l+s,h+s] p``.
        (A delayed until keeps its delay: its left operand must hold from the delayed position
        on, not from now.) A strong delay of ``false`` is ``false``, a weak one of ``true`` is
        ``true``; the others stay atoms (``F[2,2] true``: the trace has at least 3 letters).
        """
        kind = EVENTUALLY if strong else ALWAYS
        if steps == 0 or operand == (self.false if strong else self.true):
            return operand
        cubes = self.forms[operand]
        if len(cubes) == 1:
            (cube,) = cubes
            if len(cube) == 1:
                (only,) = cube
                inner_kind, lo, hi, inner, _ = self.atoms[only]
                if inner_kind == kind and hi != INF:
                    return self.atom_form(self.atom((kind, lo + steps, hi + steps, inner, 0)))
        return self.atom_form(self.atom((kind, steps, steps, operand, 0)))

    def point(self, kind: str, operand: int) -> int:
        """``operand`` at the next letter, strong (``kind`` F: the letter must exist) or weak
        (G: true when the trace ends first): the last step of a delay. It is ``operand`` itself
        when that already has the right value at the end of a trace (:meth:`end_value`), else
        the atom ``F[0,0] operand`` or ``G[0,0] operand``."""
        if self.end_value(operand) == (kind == ALWAYS):
            return operand
        return self.atom_form(self.atom((kind, 0, 0, operand, 0)))

    def end_value(self, form: int) -> bool:
        """Whether the obligation ``form`` holds on the empty suffix, at the end of a finite
        trace (:mod:`mitlc.automata.ends`): some cube whose every atom does; a literal, an
        ``F`` or ``U`` atom (windows, points and strong delays) do not, a ``G`` or ``R`` atom
        (windows, points and weak delays) does."""
        found = self._ends.get(form)
        if found is None:
            atoms = self.atoms
            found = self._ends[form] = any(
                all(atoms[a][0] in _HOLD_AT_END for a in cube) for cube in self.forms[form]
            )
        return found

    # --- Boolean operations ---------------------------------------------------------------------

    def or_(self, f: int, g: int) -> int:
        """The disjunction of two forms."""
        if f == g or g == self.false or f == self.true:
            return f
        if f == self.false or g == self.true:
            return g
        key = (f, g) if f < g else (g, f)
        found = self._or_cache.get(key)
        if found is None:
            found = self.form(self._absorb(self.forms[f] | self.forms[g]))
            self._or_cache[key] = found
        return found

    def and_(self, f: int, g: int) -> int:
        """The conjunction of two forms (the product of their cubes)."""
        if f == g or g == self.true or f == self.false:
            return f
        if f == self.true or g == self.false:
            return g
        key = (f, g) if f < g else (g, f)
        found = self._and_cache.get(key)
        if found is None:
            cubes = set()
            for left in self.forms[f]:
                for right in self.forms[g]:
                    cube = self._cube(left | right)
                    if cube is not None:
                        cubes.add(cube)
            found = self.form(self._absorb(cubes))
            self._and_cache[key] = found
        return found

    def substitute(self, form: int, replace: Callable[[int], int]) -> int:
        """``form`` with every atom replaced by the form ``replace(atom)``.

        The disjunction of the cubes' conjunctions is the set of minimal cubes of their union.
        Past :data:`SEQUENTIAL_CUBES` cubes it is taken at once, in time linear in the cubes (a
        state of ``n`` pending windows has ``n`` cubes); below, by :meth:`or_` one conjunction at
        a time, as before. The two give the same form, but the order in which the new form's
        cubes are iterated (so the order later atoms are made in, and the order of the atoms of
        a printed obligation) depends on how it was built: the small forms of every shipped and
        tested formula are built as they always were, so their output is unchanged."""
        cubes = self.forms[form]
        if len(cubes) == 1:
            (cube,) = cubes
            if len(cube) == 1:  # a single atom: what the loop below gives, without the loop
                (only,) = cube
                return replace(only)
        if len(cubes) <= SEQUENTIAL_CUBES:
            return self._substitute_sequential(cubes, replace)
        found: set[Cube] = set()
        for cube in cubes:
            conjunction = self._conjoin(cube, replace)
            if conjunction == self.true:
                return self.true
            found |= self.forms[conjunction]
        return self.union_of_cubes(found)

    def union_of_cubes(self, found: set[Cube] | frozenset[Cube]) -> int:
        """The disjunction of a set of cubes: ``true`` when it holds the empty cube, else the
        form of its minimal cubes."""
        if frozenset() in found:
            return self.true
        if len(found) == 1:
            return self.form(frozenset(found))
        return self.form(self._absorb(found))

    def _substitute_sequential(self, cubes: Form, replace: Callable[[int], int]) -> int:
        result = self.false
        for cube in cubes:
            result = self.or_(result, self._conjoin(cube, replace))
            if result == self.true:
                break
        return result

    def _conjoin(self, cube: Cube, replace: Callable[[int], int]) -> int:
        """The conjunction of ``replace(atom)`` over the atoms of ``cube`` (false at once)."""
        conjunction = self.true
        for atom in cube:
            conjunction = self.and_(conjunction, replace(atom))
            if conjunction == self.false:
                break
        return conjunction

    def all_of(self, forms: Iterable[int]) -> int:
        """The conjunction of several forms."""
        result = self.true
        for f in forms:
            result = self.and_(result, f)
        return result

    def any_of(self, forms: Iterable[int]) -> int:
        """The disjunction of several forms."""
        result = self.false
        for f in forms:
            result = self.or_(result, f)
        return result

    # --- simplification -------------------------------------------------------------------------

    def _cube(self, atoms: frozenset[int]) -> Cube | None:
        """Simplify a conjunction of atoms: ``None`` if it is contradictory. An atom implied
        by another is dropped; only atoms of one operator with the same operands can imply
        each other (:meth:`implies`), so only those are compared."""
        table, ids = self.atoms, self._atom_ids
        shapes: dict[tuple[str, int, int], list[int]] = {}
        shared = False
        for a in atoms:
            kind, x, y, left, right = table[a]
            if kind == LIT:
                if ids.get((LIT, x, 1 - y, 0, 0)) in atoms:
                    return None
                continue
            group = shapes.get((kind, left, right))
            if group is None:
                shapes[(kind, left, right)] = [a]
            else:
                group.append(a)
                shared = True
        if not shared:
            return atoms
        kept = set(atoms)
        for group in shapes.values():
            for a in group if len(group) > 1 else ():
                for b in group:
                    if a != b and a in kept and b in kept and self.implies(a, b):
                        kept.discard(b)
        return frozenset(kept)

    def implies(self, a: int, b: int) -> bool:
        """Syntactic implication between two atoms with the same operator and operands."""
        ka, la, ha, xa, ya = self.atoms[a]
        kb, lb, hb, xb, yb = self.atoms[b]
        if ka != kb or xa != xb or ya != yb or ka == LIT:
            return False
        inside = _within((la, ha), (lb, hb))  # [la,ha] within [lb,hb]
        if ka == EVENTUALLY:
            return inside
        if ka in (ALWAYS, RELEASE):
            return _within((lb, hb), (la, ha))
        # until: a witness in [la,ha] is one in [lb,hb] when lb <= la and ha <= hb
        return inside

    def _absorb(self, cubes: Iterable[Cube]) -> Form:
        """Drop every cube that contains another cube (``x | x & y`` is ``x``), then every cube
        that implies another (:meth:`_subsume`).

        Only a shorter cube can be contained in a cube (two distinct cubes of one length never
        are), so each cube is compared with the kept cubes shorter than it: a disjunction of
        ``n`` single atoms costs ``n``, not ``n * n``."""
        return self._subsume(self._contained(cubes))

    def _subsume(self, cubes: frozenset[Cube]) -> Form:
        """Drop every cube that implies another cube of ``cubes`` (``x | y`` is ``y`` when
        ``x -> y``). Beyond containment, a cube implies another only through two distinct atoms
        of one operator with the same operands (:meth:`implies`), so only the cubes holding
        such an atom are compared, pairwise; implication between reduced cubes is a partial
        order, so every dropped cube has a kept one it implies. The result does not depend on
        the order the cubes were multiplied out in: one order may leave a cube that only
        *implies* another (an atom of it dropped by :meth:`_cube` as implied within the cube)
        where the other leaves one that contains it; both are dropped here (issue 22 met 34 and
        35 states for one formula, eager and lazy, before)."""
        if len(cubes) < 2:
            return cubes
        groups: dict[tuple[str, int, int], set[int]] = {}
        atoms = self.atoms
        for cube in cubes:
            for a in cube:
                kind, _, _, left, right = atoms[a]
                if kind != LIT:
                    groups.setdefault((kind, left, right), set()).add(a)
        shape_of = {a: shape for shape, group in groups.items() if len(group) > 1 for a in group}
        if not shape_of:
            return cubes
        # A cube implies another only if it has every atom of the other that no other atom
        # implies (literals, and atoms alone in their shape) and every shape of its others:
        # two set inclusions, checked before the atoms are.
        summary = {}
        for cube in cubes:
            shapes = frozenset(shape_of[a] for a in cube if a in shape_of)
            if shapes:
                summary[cube] = (cube.difference(shape_of), shapes)
        dropped = {
            stronger
            for stronger, (own, shapes) in summary.items()
            for weaker, (other_own, other_shapes) in summary.items()
            if stronger is not weaker
            and other_own <= own
            and other_shapes <= shapes
            and self._cube_implies(stronger, weaker)
        }
        return cubes - dropped if dropped else cubes

    def _cube_implies(self, stronger: Cube, weaker: Cube) -> bool:
        """Whether every atom of ``weaker`` is an atom of ``stronger`` or implied by one
        (:meth:`implies`, which holds on finite traces and at their end too, now that a strong
        delay ``F[k,k] p`` fails there as a window ``F[l,h] p`` around ``k`` does, and a weak
        ``G[k,k] p`` holds as ``G[l,h] p`` does)."""
        return all(b in stronger or any(self.implies(a, b) for a in stronger) for b in weaker)

    @staticmethod
    def _contained(cubes: Iterable[Cube]) -> Form:
        """Drop every cube that contains another cube (see :meth:`_absorb`)."""
        ordered = sorted(set(cubes), key=len)
        kept: list[Cube] = []
        length, shorter = -1, 0  # kept[:shorter]: the kept cubes shorter than the current one
        for cube in ordered:
            if len(cube) != length:
                length, shorter = len(cube), len(kept)
            if not any(kept[i] <= cube for i in range(shorter)):
                kept.append(cube)
        return frozenset(kept)


def _within(inner: tuple[int, int], outer: tuple[int, int]) -> bool:
    """``[inner] ⊆ [outer]`` for intervals whose upper bound may be ``INF``."""
    (li, hi_), (lo, ho) = inner, outer
    if li < lo:
        return False
    if ho == INF:
        return True
    return hi_ != INF and hi_ <= ho


@dataclass(frozen=True, slots=True)
class Letter:
    """A letter as the set of indices of the true propositions (bit i for proposition i)."""

    bits: int

    def holds(self, prop: int) -> bool:
        """Whether proposition ``prop`` is true in this letter."""
        return bool(self.bits >> prop & 1)

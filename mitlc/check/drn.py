"""The product in Storm's explicit DRN format, for checking mitlc against Storm.

With costs, each action carries its expected immediate cost in the reward model ``cost``.
State labels: ``init``; ``acc0`` … on the states whose world-action choices are in that
acceptance set (the marks of a product transition depend only on its source, so this
state-based reading accepts the same runs; jumps never return to their source); ``satisfied``
and ``violated`` on the two absorbing states; ``end`` on the states where an episode that stops
there succeeds by the trace it read (:func:`mitlc.product.explicit.product_ends`; the
satisfied state among them), so that the success of an episode of ``H`` steps without
epsilon jumps or acceptance sets is Storm's ``Pmax=? [F[H,H] "end"]``. Only states reachable
from the initial state are written (Storm's LTL checker fails on labelled unreachable
states), numbered breadth-first from the start states: the start states first (``0`` when
there is one), then each state after the first one that reaches it. Storm builds its product
with the task's automaton from every state of the model when it checks a property for all
states (stormpy's default), and sizes that product's matrix by its highest target: a model
whose last state nothing reaches (a start state numbered last, as product order numbers it)
can then make Storm fail with ``Invalid item count (n) of state labeling (states: n - 1)``.
Breadth-first, every state but the start states is reached from one before it.

A world whose start is drawn (:attr:`mitlc.worlds.model.World.start_distribution`) has several
``init`` states; a comment line gives their probabilities, and the probability mitlc reports is
the average of Storm's values at those states weighted by them.
"""

from __future__ import annotations

from mitlc.automata.ends import END_HOLDS
from mitlc.product.explicit import SATISFIED, VIOLATED, Product, product_ends
from mitlc.worlds.model import FloatArray


def reachable(product: Product) -> list[int]:
    """The product states reachable from the start states, in increasing order."""
    t = product.transitions
    seen = set(starts(product))
    stack = list(seen)
    while stack:
        x = stack.pop()
        for c in range(int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])):
            for y in t.targets[int(t.indptr[c]) : int(t.indptr[c + 1])].tolist():
                if y not in seen:
                    seen.add(y)
                    stack.append(y)
    return sorted(seen)


def breadth_first(product: Product) -> list[int]:
    """The reachable product states in the order :func:`to_drn` numbers them: the start states,
    then every other state in breadth-first order from them (a state's choices in order)."""
    t = product.transitions
    order = list(starts(product))
    seen = set(order)
    index = 0
    while index < len(order):
        x = order[index]
        index += 1
        lo, hi = int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])
        for y in t.targets[int(t.indptr[lo]) : int(t.indptr[hi])].tolist():
            if y not in seen:
                seen.add(y)
                order.append(y)
    return order


def starts(product: Product) -> dict[int, float]:
    """The start states of the product and their probabilities."""
    return dict(product.starts)


def to_drn(product: Product, costs: FloatArray | None = None) -> str:
    """The DRN text of ``product`` (its reachable part, numbered breadth-first); with
    ``costs`` (an expected immediate cost per choice: ``ProductCosts.choice`` of
    :func:`mitlc.product.costs.product_costs`), a reward model ``cost`` of those action
    rewards, so that the least expected cost within ``H`` steps among the policies succeeding
    with probability at least ``p`` is Storm's
    ``multi(P>=p [F<=H "satisfied"], R{"cost"}min=? [C<=H])``."""
    states = breadth_first(product)
    number = {x: i for i, x in enumerate(states)}
    choices = sum(int(product.choice_ptr[x + 1] - product.choice_ptr[x]) for x in states)
    first = starts(product)
    lines = [
        "// mitlc product",
        *(
            ["// start distribution: " + ", ".join(f"{number[x]}: {p!r}" for x, p in first.items())]
            if len(first) > 1
            else []
        ),
        "@type: MDP",
        "@parameters",
        "",
        "@reward_models",
        "cost" if costs is not None else "",
        "@nr_states",
        str(len(states)),
        "@nr_choices",
        str(choices),
        "@model",
    ]
    t = product.transitions
    ends = product_ends(product)
    for x in states:
        lo, hi = int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])
        marks = 0
        for c in range(lo, hi):
            if product.action[c] >= 0:
                marks |= int(product.marks[c])
        labels = ["init"] if x in first else []
        labels += [f"acc{k}" for k in range(product.num_sets) if marks >> k & 1]
        labels += ["satisfied"] if x == SATISFIED else []
        labels += ["end"] if ends[x] == END_HOLDS else []
        labels += ["violated"] if x == VIOLATED else []
        head = f"state {number[x]}"
        lines.append(f"{head} " + " ".join(labels) if labels else head)
        for index, c in enumerate(range(lo, hi)):
            reward = f" [{float(costs[c])!r}]" if costs is not None else ""
            lines.append(f"\taction {index}{reward}")
            for j in range(int(t.indptr[c]), int(t.indptr[c + 1])):
                lines.append(f"\t\t{number[int(t.targets[j])]} : {float(t.probs[j])!r}")
    return "\n".join(lines) + "\n"


def labels_present(product: Product) -> set[str]:
    """The labels :func:`to_drn` writes (Storm rejects a property naming any other)."""
    present = {"init"}
    ends = product_ends(product)
    for x in reachable(product):
        present |= {"end"} if ends[x] == END_HOLDS else set()
        present |= {"satisfied"} if x == SATISFIED else set()
        present |= {"violated"} if x == VIOLATED else set()
        for c in range(int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])):
            if product.action[c] >= 0:
                present |= {f"acc{k}" for k in range(product.num_sets) if product.marks[c] >> k & 1}
    return present


def storm_label(product: Product, name: str) -> str:
    """``"name"`` in a Storm property, or ``false`` when no reachable state has the label."""
    return f'"{name}"' if name in labels_present(product) else "false"


def storm_property(product: Product) -> str:
    """Storm's property for the maximal probability of satisfying the formula (a constant one
    when a label it needs is on no reachable state: Storm rejects unknown labels)."""
    present = labels_present(product)
    if product.num_sets == 0:
        return 'Pmax=? [G !"violated"]' if "violated" in present else "Pmax=? [G true]"
    names = [f"acc{k}" for k in range(product.num_sets)]
    if not set(names) <= present:
        return "Pmax=? [F false]"
    return "Pmax=? [" + " & ".join(f'(G F "{name}")' for name in names) + "]"


DOT_LIMIT = 2_000
"""Products with more states are not drawn."""


def to_product_dot(product: Product, cells: list[tuple[int, ...]], actions: tuple[str, ...]) -> str:
    """A DOT drawing of a small product: states ``(row,col) q``, one edge per choice and
    target, labelled with the action (``ε→q`` for a jump) and its probability."""
    if product.num_states > DOT_LIMIT:
        raise ValueError(
            f"{product.num_states} product states: too many to draw (at most {DOT_LIMIT})"
        )
    lines = [
        "digraph product {",
        "  rankdir=LR;",
        '  node [shape=box, style=rounded, fontname="Helvetica"];',
    ]
    t = product.transitions
    for x in reachable(product):
        if x == VIOLATED:
            label, extra = "violated", ", style=dashed"
        elif x == SATISFIED:
            label, extra = "satisfied", ", peripheries=2"
        else:
            r, c = cells[int(product.world_state[x])]
            label, extra = f"({r},{c}) q{int(product.automaton_state[x])}", ""
        if x == product.initial:
            extra += ", penwidth=2"
        lines.append(f'  s{x} [label="{label}"{extra}];')
        for choice in range(int(product.choice_ptr[x]), int(product.choice_ptr[x + 1])):
            a = int(product.action[choice])
            name = "" if product.world_state[x] < 0 else actions[a] if a >= 0 else f"ε→q{-1 - a}"
            for j in range(int(t.indptr[choice]), int(t.indptr[choice + 1])):
                p = float(t.probs[j])
                lines.append(f'  s{x} -> s{int(t.targets[j])} [label="{f"{name} {p:g}".strip()}"];')
    lines.append("}")
    return "\n".join(lines) + "\n"

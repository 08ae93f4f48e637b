"""The product of a world and an automaton: explicit (for checking) and on the fly (a gymnasium
environment, for learning), with the same conventions (see ``DESIGN.md``, "Product, check,
learn").

The environment's names are loaded on first use, so that checking does not import gymnasium;
importing :mod:`mitlc.product.env` (or using any of its names here) registers
``mitlc/Product-v0`` with gymnasium.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

from mitlc.product.explicit import SATISFIED, VIOLATED, Product, build_product

if TYPE_CHECKING:
    from mitlc.product.env import ENV_ID, ProductEnv, make_env

_LAZY = frozenset({"ENV_ID", "ProductEnv", "make_env"})

__all__ = [
    "ENV_ID",
    "SATISFIED",
    "VIOLATED",
    "Product",
    "ProductEnv",
    "build_product",
    "make_env",
]


def __getattr__(name: str) -> Any:
    """The environment's names, imported on first use."""
    if name in _LAZY:
        return getattr(import_module("mitlc.product.env"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")

"""Axis labels from identifiers: the mathematical symbol an identifier spells (``omega`` is
``\\omega``, ``q2`` is ``q_2``, ``q1dot`` is ``\\dot q_1``), and a quantity's label from what its
family declares (``Presentation.quantity_labels``), else that symbol, else its words
(``sticking_time`` is "sticking time"). Figures label their axes with these, never with a
raw identifier. Plain strings (matplotlib mathtext between ``$``), no matplotlib import."""

from __future__ import annotations

import re
from collections.abc import Mapping

#: Greek letters spelled out in identifiers (lower case; a capital first letter gives the
#: capital letter where LaTeX has one)
GREEK = ("alpha", "beta", "gamma", "delta", "epsilon", "zeta", "eta", "theta", "iota",
         "kappa", "lambda", "mu", "nu", "xi", "pi", "rho", "sigma", "tau", "upsilon", "phi",
         "chi", "psi", "omega")
#: capital Greek letters LaTeX writes as commands (the others are Latin capitals)
CAPITAL_GREEK = {"Gamma", "Delta", "Theta", "Lambda", "Xi", "Pi", "Sigma", "Upsilon", "Phi",
                 "Psi", "Omega"}

#: ``name``, an optional index of digits, an optional ``dot`` (time derivative)
_SYMBOL = re.compile(r"^(?P<base>[A-Za-z]+?)(?P<index>\d+)?(?P<dot>dot)?$")
#: longest Latin base that is read as one symbol (``m``, ``L``, ``qd``), not as a word
_LATIN_SYMBOL_LENGTH = 2


def _letter(base: str) -> str | None:
    """The LaTeX of ``base`` as one symbol: a Greek name, or one or two Latin letters; None
    for a word."""
    if base.lower() in GREEK:
        if base[0].isupper():
            return f"\\{base}" if base in CAPITAL_GREEK else None
        return f"\\{base}"
    if len(base) <= _LATIN_SYMBOL_LENGTH:
        return base
    return None


def math_symbol(name: str) -> str | None:
    """The symbol an identifier spells, as mathtext without ``$``: ``omega`` ->
    ``\\omega``, ``q2`` -> ``q_{2}``, ``q1dot`` -> ``\\dot{q}_{1}``, ``zeta_1`` -> ``\\zeta_{1}``,
    ``T`` -> ``T``; None where it is a word (``restitution``, ``sticking_time``)."""
    head, _, sub = name.partition("_")
    m = _SYMBOL.match(head)
    if m is None:
        return None
    letter = _letter(m["base"])
    if letter is None:
        return None
    index = m["index"] or ""
    if sub:
        sub_symbol = math_symbol(sub) if not sub.isdigit() else sub
        if index or sub_symbol is None or len(sub) > 3:
            return None
        index = sub_symbol
    body = f"\\dot{{{letter}}}" if m["dot"] else letter
    return f"{body}_{{{index}}}" if index else body


def quantity_label(name: str, declared: Mapping[str, str] | None = None) -> str:
    """The axis label of quantity ``name``: the family's declared label, else its symbol in
    mathtext (``$\\omega$``), else its words (``sticking time``)."""
    if declared and name in declared:
        return declared[name]
    symbol = math_symbol(name)
    return f"${symbol}$" if symbol is not None else name.replace("_", " ")


def is_raw_identifier(label: str) -> bool:
    """Whether an axis label is a bare identifier (letters, digits and underscores with an
    underscore or a digit in it, or a Greek name spelled out): what a figure should not
    show."""
    text = label.strip()
    if not re.fullmatch(r"[A-Za-z][A-Za-z0-9_]*", text):
        return False
    return "_" in text or any(c.isdigit() for c in text) or text.lower() in GREEK


__all__ = ["GREEK", "is_raw_identifier", "math_symbol", "quantity_label"]

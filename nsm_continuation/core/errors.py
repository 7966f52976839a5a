"""The errors every layer raises: :class:`CaseError` for bad input (exit status 2, one line naming
the key, before any computation). Kept free of heavy imports so that the command line can tell a
bad input from a bug without loading pydantic or CasADi."""


class CaseError(ValueError):
    """Bad input: the message names the key and what is wrong."""


def short_text(text: str, limit: int = 120) -> str:
    """A path or value shortened for a one-line message."""
    return text if len(text) <= limit else f"{text[:50]}...{text[-50:]} ({len(text)} characters)"

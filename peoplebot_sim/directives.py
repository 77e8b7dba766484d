"""The directives of the world: the vocabulary of behaviours and the four motor directives, and the
wheel commands that drive both robots (``perception.drive``: one definition for the world, the
student and the inference of directives from motion)."""

from __future__ import annotations

from associator.encoding import DIRECTIVES, WORDS, directive_index
from perception.drive import DriveSpeeds

__all__ = ["DIRECTIVES", "WORDS", "DriveSpeeds", "directive_index", "word_index"]


def word_index(word: str) -> int:
    """Returns the index of a word in ``WORDS``."""
    try:
        return WORDS.index(word)
    except ValueError:
        raise ValueError(f"unknown word {word!r}; allowed: {', '.join(WORDS)}") from None

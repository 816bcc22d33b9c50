"""A small finite-state grammar: subject – verb – adjective/object triplets to English sentences.

Thesis 5.1: the subject comes from the object class and the track id ("Person 3"), the verb is a
motion verb (``enters``, ``exits``, ``appears``, ``vanishes``, ``moves``, ``stays``, ``merge``,
``split``), an interaction verb (``interacts with``, ``walk together``, ``move together``) or a
pose attribute (``opens``, ``closes``), and the adjective is a direction (``left``, ``right``,
``upwards``, ``downwards`` and their pairs) or a side of the image. Every sentence ends with its
frame (or time) range. The grammar is finite: :data:`VERBS` and :data:`ADJECTIVES` list every
word it can say, and :func:`render` rejects anything else.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass, field

from artmotion.errors import InputError
from artmotion.io.events import SIDES

#: verb -> category; the grammar says nothing else.
VERBS = {
    "enters": "motion",
    "exits": "motion",
    "appears": "motion",
    "vanishes": "motion",
    "moves": "motion",
    "stays": "motion",
    "merge": "motion",
    "split": "motion",
    "interacts with": "interaction",
    "walk together": "interaction",
    "move together": "interaction",
    "move towards each other": "interaction",
    "move apart": "interaction",
    "opens": "pose",
    "closes": "pose",
}
DIRECTIONS = ("left", "right", "upwards", "downwards")
ADJECTIVES = set(DIRECTIONS) | set(SIDES) | {
    f"{h} and {v}" for h in ("left", "right") for v in ("upwards", "downwards")
}

# How a side reads after "enters"/"exits".
_ENTER_SIDE = {"left": "from the left", "right": "from the right", "top": "from the top", "bottom": "from the bottom"}
_EXIT_SIDE = {"left": "to the left", "right": "to the right", "top": "at the top", "bottom": "at the bottom"}


@dataclass
class Triplet:
    """One description: ``subject verb adjective/object`` over ``frames`` (first, last)."""

    subject: str
    verb: str
    adjective: str | None = None
    object: str | None = None
    frames: tuple[int, int] = (1, 1)
    tracks: list[int] = field(default_factory=list)
    times: tuple[float, float] | None = None
    sentence: str = ""

    def to_dict(self) -> dict:
        d = asdict(self)
        d["frames"] = list(self.frames)
        if self.times is None:
            d.pop("times")
        else:
            d["times"] = [round(t, 3) for t in self.times]
        return d


def noun_phrase(cls: str, track: int | None, *, capital: bool) -> str:
    """``("person", 3)`` -> ``"Person 3"`` (or ``"person 3"`` inside a sentence); ``cls`` must be text."""
    if not isinstance(cls, str):
        raise InputError(f"a class name must be text, got {cls!r}")
    word = cls.strip() or "object"
    word = word[0].upper() + word[1:] if capital else word.lower()
    return word if track is None else f"{word} {track}"


def _span(frames: tuple[int, int], times: tuple[float, float] | None) -> str:
    """The moment or the stretch of a sentence; times to 0.1 s, or as many more decimals (up to 4)
    as tell a stretch's two ends apart ("from 2.5 s to 2.5 s (frames 63-64)" read as an instant)."""
    a, b = frames
    if times is not None:
        ta, tb = times
        d = 1
        while a != b and d < 4 and f"{ta:.{d}f}" == f"{tb:.{d}f}":
            d += 1
        return f"at {ta:.1f} s (frame {a})" if a == b else f"from {ta:.{d}f} s to {tb:.{d}f} s (frames {a}-{b})"
    return f"at frame {a}" if a == b else f"from frame {a} to frame {b}"


def render(t: Triplet) -> str:
    """The sentence for a triplet, following the grammar; also stored in ``t.sentence``."""
    if t.verb not in VERBS:
        raise ValueError(f"verb {t.verb!r} is not in the grammar")
    if t.adjective is not None and t.adjective not in ADJECTIVES:
        raise ValueError(f"adjective {t.adjective!r} is not in the grammar")
    span = _span(t.frames, t.times)
    v, adj = t.verb, t.adjective
    if v == "enters":
        middle = f"enters {_ENTER_SIDE[adj]}" if adj in _ENTER_SIDE else "enters"
    elif v == "exits":
        middle = f"exits {_EXIT_SIDE[adj]}" if adj in _EXIT_SIDE else "exits"
    elif v in ("appears", "vanishes"):
        middle = f"{v} inside the image"
    elif v == "moves":
        middle = f"moves {adj}" if adj else "moves"
    elif v == "stays":
        middle = "stays in place"
    elif v in ("merge", "split"):
        middle = f"{v} into one group" if v == "merge" else "split from their group"
    elif v == "interacts with":
        middle = f"interacts with {t.object}"
    elif v in ("walk together", "move together"):
        middle = v + (f" {adj}" if adj else "")
    elif v in ("move towards each other", "move apart"):
        middle = v
    else:  # opens / closes
        middle = v
    sentence = f"{t.subject} {middle} {span}."
    t.sentence = sentence
    return sentence


def join_subjects(phrases: list[str]) -> str:
    """``["Person 2", "person 5", "person 7"]`` -> ``"Person 2, person 5 and person 7"``."""
    if len(phrases) == 1:
        return phrases[0]
    return ", ".join(phrases[:-1]) + " and " + phrases[-1]

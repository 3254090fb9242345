"""The unknowns of a calibration by kind, in words a reader knows: joint placements, the
instrument registration, the tool."""

from __future__ import annotations

from pincal.identify.calibration import Calibration

#: What each model's parameters are, for the summary's words.
MODEL_WORDS = {
    "placements": "joint placement",
    "poe": "twist (POE)",
    "mdh": "modified DH",
    "offsets": "joint offset",
}
#: What the unknowns beside the model's are, by the first part of their names.
GROUP_WORDS = {
    "instrument": "instrument registration",
    "tool": "tool",
    "point": "fixed-point position",
    "marker": "marker points",
}


def parameter_groups(cal: Calibration) -> list[tuple[str, int, int]]:
    """The unknowns of ``cal`` by kind, in order: (words, identifiable, all), e.g.
    ``("joint placement", 18, 36)``, ``("instrument registration", 6, 6)``, ``("tool", 3, 3)``."""
    n_model = cal.model.n_params
    keep = cal.identifiability.identifiable
    groups: dict[str, list[int]] = {}
    for i, name in enumerate(cal.names):
        if i < n_model:
            words = MODEL_WORDS.get(cal.model.kind, cal.model.kind)
        else:
            words = GROUP_WORDS.get(name.split(".")[0], "effect")
        counts = groups.setdefault(words, [0, 0])
        counts[0] += int(bool(keep[i]))
        counts[1] += 1
    return [(words, n, total) for words, (n, total) in groups.items()]

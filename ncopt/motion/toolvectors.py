"""Tool vectors, which need no machine data: Fanuc ``G43.5 I J K`` and Sinumerik ``A3= B3=
C3=`` under TRAORI; the vector in force after every line, and why a line's cannot be
used."""

from __future__ import annotations

import numpy as np

from ncopt.motion.modal import ffill
from ncopt.motion.toolaxis import (G_LENGTH_GROUP, G_VECTOR_TCP, ORIENTATION_ADDRESS,
                                   VECTOR_LETTERS, before)
from ncopt.runtime.errors import NcoptError


def tool_vectors(prog, lines, executed, keywords, tcp_on, r):
    """Tool vector in force after each line (n, 3), NaN where none, and why a line's
    vector cannot be used (n,) int16.  Raises NcoptError for a vector of zero length."""
    n = lines.n
    vec = np.full((n, 3), np.nan)
    why = np.zeros(n, dtype=np.int16)
    length = ffill(np.where(executed, lines.g_group(G_LENGTH_GROUP), np.nan), 490.0)
    fanuc = (length == G_VECTOR_TCP) & executed
    sinumerik = _sinumerik_section(prog, lines, executed, keywords)
    for active, letters, name in ((fanuc, "IJK", "G43.5 I J K"),
                                  (sinumerik & tcp_on, VECTOR_LETTERS, "A3= B3= C3=")):
        if not active.any():
            continue
        got = _vector_in_force(prog, lines, active, letters, name)
        vec = np.where(np.isnan(got), vec, got)
    stray = np.full(n, np.nan)  # A3= where TRAORI is not in force: until TRAORI or TRAFOOF
    stray[lines.present_any(VECTOR_LETTERS) & executed & ~(sinumerik & tcp_on)] = 1.0
    for i, head in keywords.items():
        if head in ("TRAORI", "TRAFOOF"):
            stray[i] = 0.0
    why[ffill(stray, 0.0) > 0] = r.code("A3= B3= C3= without TRAORI in force; ncopt does "
                                        "not read them")
    why[_orientation_opaque(prog, lines, executed, keywords)] = r.code(
        "Sinumerik orientation given in a form ncopt does not read (A2=, A4=, LEAD=, a "
        "computed A3=...); only A3= B3= C3= with numbers are read")
    mks = _keyword_state(lines.n, keywords, {"ORIMKS"}, {"ORIWKS", "TRAFOOF"}, lines, executed)
    has = ~np.isnan(vec).any(axis=1)
    why[has & mks] = r.code("ORIMKS: tool vectors in machine coordinates are not read; "
                            "program them with ORIWKS")
    return vec, why


def _vector_in_force(prog, lines, active, letters, name) -> np.ndarray:
    """(n, 3) the vector given in the section ``active`` (NaN before the first)."""
    idx = np.arange(lines.n)
    has = lines.present_any(letters) & active
    comp = np.stack([np.nan_to_num(lines.value(c)) for c in letters], axis=1)
    zero = has & (np.linalg.norm(comp, axis=1) == 0)
    if zero.any():
        i = int(np.flatnonzero(zero)[0])
        raise NcoptError(f"the tool vector ({name}) has no direction; give the tool axis",
                         prog.path, i + 1, 1)
    starts = active & ~before(active, False)
    last_set = np.maximum.accumulate(np.where(has, idx, -1))
    last_start = np.maximum.accumulate(np.where(starts, idx, -1))
    given = active & (last_set >= 0) & (last_set >= last_start)
    return np.where(given[:, None], comp[np.maximum(last_set, 0)], np.nan)


def _keyword_state(n, keywords, on_words, off_words, lines, executed) -> np.ndarray:
    """(n,) bool: from a line with a keyword of ``on_words`` until one of ``off_words``."""
    state = np.full(n, np.nan)
    for i, head in keywords.items():
        if head in on_words:
            state[i] = 1.0
        elif head in off_words:
            state[i] = 0.0
    state[lines.has_m({2, 30}) & executed] = 0.0
    return ffill(state, 0.0) > 0


def _sinumerik_section(prog, lines, executed, keywords) -> np.ndarray:
    """(n,) bool: from TRAORI until TRAFOOF (or the program end)."""
    return _keyword_state(lines.n, keywords, {"TRAORI"}, {"TRAFOOF"}, lines, executed)


def _orientation_opaque(prog, lines, executed, keywords) -> np.ndarray:
    """(n,) bool: from a Sinumerik orientation ncopt does not read until TRAFOOF."""
    heads = {i: "ORI" for i, h in keywords.items() if ORIENTATION_ADDRESS.match(h)}
    heads.update({i: h for i, h in keywords.items() if h == "TRAFOOF"})
    return _keyword_state(lines.n, heads, {"ORI"}, {"TRAFOOF"}, lines, executed)

"""json_floats writes every float as ``repr`` (and so ``json``) does: values rounded to 6
decimals (its table path) and every other kind (its ``repr`` path) side by side."""

from __future__ import annotations

import json

import numpy as np
import pytest

from swarmplan.io.json_floats import Interleaved, float_chars


def _values(seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    y = rng.normal(0, 10.0 ** rng.integers(-6, 11, 4000), 4000)
    y = np.round(y, rng.integers(0, 10, 4000)[0]) if seed % 2 else np.round(y, 6)
    special = [0.0, -0.0, 1.0, -3.0, 1e-4, -1e-4, 9.9e-5, 5e-06, 1e-06, 0.1, 0.5, 123456.000001]
    special += [2.0**33 - 2.0**-20, -(2.0**33) + 0.5, 2.0**33, 1e16, 1e300, 5e-324, 8589934591.999999]
    y[: len(special)] = special
    return y


@pytest.mark.parametrize("seed", range(6))
def test_float_chars_equal_repr(seed):
    y = _values(seed)
    chars, start, length = float_chars(y)
    got = [chars[i, s : s + n].tobytes() for i, (s, n) in enumerate(zip(start, length, strict=True))]
    assert got == [repr(v).encode() for v in y.tolist()]


@pytest.mark.parametrize("seed", range(3))
def test_interleaved_equals_json(seed):
    y = _values(seed)[:500]
    text = Interleaved([b'{"v":['] + [b","] * (len(y) - 1) + [b'],"end":"%"}'])
    assert text.fill(y) == json.dumps({"v": y.tolist(), "end": "%"}, separators=(",", ":")).encode()
    assert (
        text.fill(y[::-1]) == json.dumps({"v": y[::-1].tolist(), "end": "%"}, separators=(",", ":")).encode()
    )
    with pytest.raises(ValueError):
        text.fill(y[:-1])


def test_no_numbers():
    assert Interleaved([b"[]"]).fill(np.zeros(0)) == b"[]"
    assert float_chars(np.zeros(0))[0].shape == (0, 24)


@pytest.mark.parametrize("compiled", [False, True])
def test_replaced_pieces_write_the_text_of_new_pieces(compiled):
    """Interleaved.replace (pieces of other lengths, some longer) writes what an Interleaved
    made from the new pieces writes, compiled or not, and again after a second replacement."""
    rng = np.random.default_rng(3)
    n = 50
    pieces = [b"[" + b"x" * int(k) + b"," for k in rng.integers(0, 12, n)] + [b"]"]
    values = np.round(rng.normal(0, 100, n), 6)
    text = Interleaved(pieces, compiled=compiled)
    text.fill(values)
    for _ in range(2):
        which = sorted(rng.choice(n + 1, 7, replace=False).tolist())
        pieces = list(pieces)
        for k in which:
            pieces[k] = b'"%s"' % (b"y" * int(rng.integers(0, 40)))
        text.replace(which, pieces)
        assert text.fill(values) == Interleaved(pieces, compiled=compiled).fill(values)

"""A quick preview's PNG (``taylorball.figures._common.save_figure``) is written at a lower
zlib level than Pillow's default: the same pixels as the default encoding, only faster."""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("matplotlib")


def _figure():
    from taylorball.figures import _common as C

    plt = C.pyplot()
    fig, ax = plt.subplots(figsize=(3, 2))
    rng = np.random.default_rng(0)
    ax.plot(rng.normal(size=300), rng.normal(size=300), "o", markersize=1)
    ax.set_title("$l$ and $r_1$")
    return fig


def test_a_quick_png_has_the_pixels_of_the_default_encoding(tmp_path, monkeypatch):
    from PIL import Image

    from taylorball.figures import _common as C

    assert C.PREVIEW_PNG_LEVEL != 6  # otherwise this compares an encoding with itself
    meta = {"quality": "quick", "study": "test"}
    (path,) = C.save_figure(_figure(), tmp_path / "preview", "quick", meta)
    monkeypatch.setattr(C, "PREVIEW_PNG_LEVEL", 6)  # Pillow's default level
    (default,) = C.save_figure(_figure(), tmp_path / "default", "quick", meta)
    a, b = np.asarray(Image.open(path)), np.asarray(Image.open(default))
    assert a.shape == b.shape and np.array_equal(a, b)
    assert path.read_bytes() != default.read_bytes()  # two encodings of the same pixels

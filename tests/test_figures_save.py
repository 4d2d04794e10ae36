"""Drawing the figures for less: a quick preview's PNG (``taylorball.figures._common.save_figure``)
is written at a lower zlib level than Pillow's default (the same pixels as the default
encoding, only faster), and log axes can label their ticks in plain text (the same labels
without mathtext parsing)."""

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


def test_log_tick_labels_in_plain_text_are_the_mathtext_labels():
    from taylorball.figures import _common as C

    assert C.plain_math(r"$\mathdefault{10^{-2}}$") == "10⁻²"
    assert C.plain_math(r"$\mathdefault{10^{3}}$") == "10³"
    assert C.plain_math(r"$\mathdefault{2\times10^{-1}}$") == "2×10⁻¹"
    assert C.plain_math(r"$\mathdefault{10^{1.5}}$") == r"$\mathdefault{10^{1.5}}$"  # not a decade form: kept
    assert C.plain_math("lag") == "lag"
    plt = C.pyplot()
    fig, ax = plt.subplots()
    ax.loglog([2.0, 400.0], [0.05, 3e3])
    before = {a: [t.get_text() for t in getattr(ax, f"get_{a}ticklabels")(which="both")] for a in "xy"}
    C.plain_log_ticks(ax)
    fig.canvas.draw()
    after = {a: [t.get_text() for t in getattr(ax, f"get_{a}ticklabels")(which="both")] for a in "xy"}
    plt.close(fig)
    assert all(after[a] == [C.plain_math(s) for s in before[a]] for a in "xy")
    assert any("⁻" in s for s in after["y"]) and not any("$" in s for s in after["x"] + after["y"])

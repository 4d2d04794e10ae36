"""The Fig. 4a/4b panel of the skeleton study (figure skeleton_fig4): the catalogued orbits of
the Fig. 4 ball at Omega = 2 solved again from their stored states (no search), over a MEGNO
map of a slice of each level; data and metadata first, the plot from them alone."""

import dataclasses
import json

import numpy as np

import taylorball as tb
from taylorball.figures import skeleton as S
from taylorball.periodic_catalog import FIG4A_SADDLE_K10


def test_fig4_panel_data_and_plot(tmp_path):
    fam = ("FIG4A_SADDLE_K10", "M_gamma", 2.02, (1, 1, 1, 1, 2, 1, 1, 1, 1), 1.0)
    cfg = dataclasses.replace(S.QUICK, fig4_map_n=5, fig4_megno_t=5.0, fig4_family=fam)
    arrays, meta = S._fig4(cfg)
    json.dumps(meta)  # the metadata is saved as JSON
    orbits = [o for o in meta["orbits"] if o["level"] == "a"]
    assert [o["name"] for o in orbits] == ["FIG4A_SADDLE_K10", "FIG4A_SADDLE_K10_R", "FIG4A_SADDLE_FOCUS_K14",
                                           "FIG4A_SADDLE_FOCUS_K14_R"]
    assert [o["type"] for o in orbits] == ["saddle", "saddle", "saddle-focus", "saddle-focus"]
    e = FIG4A_SADDLE_K10
    assert orbits[0]["k"] == e.k and abs(orbits[0]["period"] - e.period) <= 1e-9 * e.period
    pts = arrays["fig4a_orbit0_points"]
    assert pts.shape == (e.k, 3)
    # the points are the stored state's images by the section integrator (independent of the
    # shooting), the k-th image being the first point again (l mod 2 pi)
    sec = tb.poincare_section("reduced", e.ball, np.array(e.state), n_points=e.k)
    img = np.roll(np.asarray(sec.points), 1, axis=0)
    d = pts - img
    d[:, 0] = (d[:, 0] + np.pi) % (2 * np.pi) - np.pi
    assert float(np.max(np.abs(d))) <= 1e-9
    for tag in "ab":
        assert arrays[f"fig4{tag}_map_values"].shape == (5, 5)
        assert meta["levels"][tag]["n_orbits"] == sum(o["level"] == tag for o in meta["orbits"])
    # the family in H: its start is the catalogued saddle (H = 2), and it reaches the target
    f = meta["family"]
    w = arrays["fig4_family_values"]
    assert w[0] == e.levels.M_gamma and w[-1] == 2.02 and f["stopped"] == "reached" and np.all(np.diff(w) > 0)
    assert f["types"][0] == "saddle" and arrays["fig4_family_logmu"].shape == (len(w), 3)
    # ln|mu| sums to 0 (volume preservation): the same check as the orbits' own
    assert np.all(np.abs(arrays["fig4_family_logmu"].sum(axis=1)) <= 1e-10)
    figs = S._plot_fig4(arrays, {"fig4": meta, "quality": "quick", "study": "skeleton"}, tmp_path)
    assert [f.name for f in figs] == ["skeleton_fig4.png"] and figs[0].stat().st_size > 1000


def test_fig4_family_by_arclength():
    """The full form's family by pseudo-arclength (a short stretch here): it starts at the
    catalogued saddle, ends on the target's level, and its metadata is JSON."""
    arrays, meta = S._fig4_family(("FIG4A_SADDLE_K10", "M_gamma", 2.02, (1, 1, 1, 1, 3, 1, 1, 1), 1.0, "arclength"))
    json.dumps(meta)
    w = arrays["fig4_family_values"]
    assert meta["method"] == "arclength" and meta["stopped"] == "reached" and w[0] == 2.0 and w[-1] == 2.02
    assert np.all(np.abs(arrays["fig4_family_logmu"].sum(axis=1)) <= 1e-10)

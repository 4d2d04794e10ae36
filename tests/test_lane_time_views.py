"""The lanes' event callbacks read their integrator's time from views of it (heyoka's
``dtime``) that the lane pool's worker lends them (``_lanes._TimeViews``) instead of
reading ``ta.dtime`` at every crossing: the records must be those of a fresh read, the
views must follow the integrator through every way its time is set, and releasing them
(the worker does at its end, whatever ends it) must let the integrator go."""

import copy
import gc
import pickle
import weakref

import numpy as np
import pytest

from taylorball._angle_lift import _CutCollector, _CutLanes
from taylorball._lanes import _TimeViews
from taylorball.ensemble import LaneLoad, orbit_lanes


def _oscillators(cb):
    import heyoka as hy

    x, v = hy.make_vars("x", "v")
    # four lanes of x'' = -x at different amplitudes: x crosses 0 every pi
    return hy.taylor_adaptive_batch([(x, v), (v, -x)], np.array([[0.1, 0.3, -0.2, 0.5], [1.0, -0.5, 0.7, 0.2]]),
                                    nt_events=[hy.nt_event_batch(x, cb)])


def _drive(ta):
    """Every way the lane pool moves an integrator's time: propagate_until, propagate_grid,
    set_dtime (a chunk run again), set_time."""
    ta.propagate_until(np.array([10.0, 11.0, 12.0, 13.0]))
    t = np.array(ta.time)
    ta.propagate_grid(np.stack([t, t + 5.0, t + 20.0]))
    ta.set_dtime(np.array([3.0, 4.0, 5.0, 6.0]), np.array([1e-17, -2e-17, 0.0, 3e-17]))
    ta.propagate_until(np.array([40.0, 41.0, 42.0, 43.0]))
    ta.set_time(np.array([100.0, 101.0, 102.0, 103.0]))
    ta.propagate_until(np.array([130.0, 131.0, 132.0, 133.0]))
    return [(list(lane.times), [tuple(s) for s in lane.states]) for lane in ta.nt_events[0].callback.lanes]


def test_lent_views_give_the_records_of_a_fresh_read():
    ta = _oscillators(_CutLanes(4))
    views = _TimeViews(ta)  # lent before the first step, as the lane pool's worker does
    assert ta.nt_events[0].callback.time_views is not None
    held = _drive(ta)
    views.release()
    fresh_ta = _oscillators(_CutLanes(4))  # nothing lent: ta.dtime read at every crossing
    fresh = _drive(fresh_ta)
    assert fresh_ta.nt_events[0].callback.time_views is None
    assert held == fresh
    assert sum(len(t) for t, _ in held) > 4 * 30  # ~40 crossings per lane over 130 time units


def test_release_lets_the_integrator_go_and_copies_hold_nothing():
    ta = _oscillators(_CutLanes(4))
    views = _TimeViews(ta)
    ta.propagate_until(10.0)
    cb = ta.nt_events[0].callback
    assert cb.time_views is not None
    assert copy.deepcopy(ta).nt_events[0].callback.time_views is None  # a copy's callback is its own
    assert pickle.loads(pickle.dumps(cb)).time_views is None  # never a stale copy of the views
    gone = weakref.ref(ta)
    del ta, cb
    gc.collect()
    assert gone() is not None  # the views hold the integrator (a cycle through heyoka)
    views.release()
    gc.collect()
    assert gone() is None


def test_a_callback_without_lent_views_holds_nothing():
    ta = _oscillators(_CutLanes(4))
    ta.propagate_until(10.0)
    cb = ta.nt_events[0].callback
    assert cb.time_views is None and len(cb.lanes[0].times) > 2
    assert isinstance(cb.lanes[0], _CutCollector)
    gone = weakref.ref(ta)
    del ta, cb
    gc.collect()
    assert gone() is None


@pytest.mark.parametrize("workers", [1, 2])
def test_the_lane_pool_lends_the_views_and_drops_them_at_its_end(workers):
    """Through ``orbit_lanes``: during the run each worker's integrator's callback has its
    views (and records crossings with them); after the run no integrator is kept alive."""
    template = _oscillators(_CutLanes(4))
    seen = []

    def load(j):
        return LaneLoad(np.array([0.1 * (j + 1), 1.0]), np.zeros(0), 0.0, 20.0, 5.0)

    def on_chunk(ta, c):
        cb = ta.nt_events[0].callback
        seen.append((cb.time_views is not None, weakref.ref(ta)))
        own = cb.lanes[c.lane]
        n = len(own.times)
        own.times.clear()
        own.states.clear()
        return False, n if c.last else None

    orbit_lanes(template, 9, load=load, on_chunk=on_chunk, rerun=lambda j, o, t: None, workers=workers)
    assert seen and all(lent for lent, _ in seen)
    assert template.nt_events[0].callback.time_views is None  # the cached template is never lent
    gc.collect()
    assert all(ref() is None for _, ref in seen)  # the workers' copies are freed


def test_an_integrator_without_events_lends_nothing():
    import heyoka as hy

    x, v = hy.make_vars("x", "v")
    ta = hy.taylor_adaptive_batch([(x, v), (v, -x)], np.ones((2, 4)))  # nt_events raises here
    views = _TimeViews(ta)
    assert views.takers == []
    views.release()

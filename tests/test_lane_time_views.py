"""The lanes' event callbacks keep views of their integrator's time (``hold_times``)
instead of reading ``ta.dtime`` at every crossing: the records must be those of a fresh
read, the views must follow the integrator through every way its time is set, and
``release_times`` must let the integrator go."""

import copy
import gc
import pickle
import weakref

import numpy as np

from taylorball._angle_lift import _CutCollector, _CutLanes, release_times


class _FreshCut(_CutLanes):
    """The same callback reading ``ta.dtime`` at every crossing (the arithmetic before the
    views were kept)."""

    def __call__(self, ta, t, d_sgn, idx):
        self.dt = None
        super().__call__(ta, t, d_sgn, idx)


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


def test_held_views_give_the_records_of_a_fresh_read():
    held = _drive(_oscillators(_CutLanes(4)))
    fresh = _drive(_oscillators(_FreshCut(4)))
    assert held == fresh
    assert sum(len(t) for t, _ in held) > 4 * 30  # ~40 crossings per lane over 130 time units
    release_times()


def test_release_lets_the_integrator_go_and_copies_hold_nothing():
    ta = _oscillators(_CutLanes(4))
    ta.propagate_until(10.0)
    cb = ta.nt_events[0].callback
    assert cb.dt is not None  # held after the first crossing
    assert copy.deepcopy(ta).nt_events[0].callback.dt is None  # a copy's callback is its own
    assert pickle.loads(pickle.dumps(cb)).dt is None  # never a stale copy of the views
    gone = weakref.ref(ta)
    del ta, cb
    gc.collect()
    assert gone() is not None  # the views hold the integrator (a cycle through heyoka)
    release_times()
    gc.collect()
    assert gone() is None


def test_a_released_callback_fetches_the_views_again():
    ta = _oscillators(_CutLanes(4))
    ta.propagate_until(10.0)
    release_times()
    cb = ta.nt_events[0].callback
    assert cb.dt is None
    n = len(cb.lanes[0].times)
    ta.propagate_until(20.0)
    assert cb.dt is not None and len(cb.lanes[0].times) > n
    assert isinstance(cb.lanes[0], _CutCollector)
    release_times()

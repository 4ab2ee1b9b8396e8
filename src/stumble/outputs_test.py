"""What a trip writes (stumble.outputs): the motion with its walk before the trip."""

import numpy as np

from stumble.outputs import trip_motion
from stumble.pipeline import simulate_trip
from stumble.trip import Scenario


def test_the_video_shows_the_walk_before_the_trip_without_its_planting_steps():
    """``trip_motion(shown=True)`` (trip.mp4): at each heel strike in the second before
    the trip the joints move by at most 0.4 deg from one sample to the next, where the
    motion files' walk (``shown=False``, the state the trip starts from) steps by 1-2.3
    deg (a foot planted); from the trip on both are the recording, bit for bit."""
    r = simulate_trip(Scenario(mechanism="force", swing_fraction=0.5, speed_m_per_s=1.2))
    t, kept = trip_motion(r)
    t2, shown = trip_motion(r, shown=True)
    assert np.array_equal(t, t2)
    after = t >= 0
    assert np.array_equal(kept[after], shown[after])
    t_trip, pb = r.summary["trip_time_s"], r.playback
    strikes = [hs - t_trip for side in "rl" for hs in pb.events.heel_strike_s[side]
               if -1.0 < hs - t_trip < 0.0]
    assert len(strikes) == 2
    for x in strikes:
        k = int(np.searchsorted(t, x))
        step = {name: np.degrees(np.abs(q[k, 7:] - q[k - 1, 7:])).max()
                for name, q in (("kept", kept), ("shown", shown))}
        assert step["kept"] > 1.0 and step["shown"] < 0.4, (x, step)

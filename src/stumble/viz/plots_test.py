"""Joint-angle plots: PNG size, missing keys, bands, events, bad input."""

import matplotlib.image as mpimg
import numpy as np
import pytest

from stumble.errors import InputError
from stumble.viz.plots import plot_joint_angles

EXPECTED_PX = (1200, 900)  # 8 in x 6 in at 150 dpi (rows, columns)


def _curves(n=101):
    pct = np.linspace(0.0, 100.0, n)
    ph = 2 * np.pi * pct / 100.0
    angles = {
        "hip_flexion_r": 10 + 20 * np.cos(ph),
        "hip_flexion_l": 10 + 20 * np.cos(ph + np.pi),
        "knee_angle_r": -30 + 30 * np.cos(2 * ph),
        "knee_angle_l": -30 + 30 * np.cos(2 * ph + np.pi),
        "ankle_angle_r": 8 * np.sin(ph),
        "ankle_angle_l": 8 * np.sin(ph + np.pi),
    }
    return pct, angles


def _read_png(path):
    assert path.exists()
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    img = mpimg.imread(path)
    return img


def test_full_plot_is_a_png_of_expected_size(tmp_path):
    pct, angles = _curves()
    spread = {k: np.full_like(v, 3.0) for k, v in angles.items()}
    out = plot_joint_angles(tmp_path / "sub" / "angles.png", pct, angles,
                            events={"toe_off_percent": {"r": 62.0, "l": 12.0}},
                            title="test gait", spread_deg=spread)
    assert out == tmp_path / "sub" / "angles.png"
    img = _read_png(out)
    assert img.shape[:2] == EXPECTED_PX
    assert img[..., :3].std() > 0.01  # something was drawn


def test_foot_angles_add_a_fourth_panel(tmp_path):
    pct, angles = _curves()
    feet = {**angles, "foot_angle_r": 20 * np.sin(np.linspace(0, 6.3, 101))}
    img = _read_png(plot_joint_angles(tmp_path / "feet.png", pct, feet,
                                      reference_deg={"foot_angle_l": feet["foot_angle_r"]}))
    assert img.shape[:2] == (1600, 900)  # 10 in x 6 in: four panels of the same height
    # the fourth panel (below the first 1200 rows' worth of three) has curves drawn
    assert img[1250:1500, 100:850, :3].std() > 0.05


def test_the_trunk_adds_a_panel_of_one_curve(tmp_path):
    """The key ``trunk_lean`` (no sides) adds a panel below the foot's: five panels."""
    pct, angles = _curves()
    wave = 20 * np.sin(np.linspace(0, 6.3, 101))
    both = {**angles, "foot_angle_r": wave, "trunk_lean": 15 + 0.2 * wave}
    img = _read_png(plot_joint_angles(tmp_path / "trunk.png", pct, both,
                                      reference_deg={"trunk_lean": 14 + 0 * wave}))
    assert img.shape[:2] == (2000, 900)  # five panels of the same height
    assert img[1650:1900, 100:850, :3].std() > 0.05  # the fifth panel has curves


def test_missing_keys_are_skipped(tmp_path):
    pct, angles = _curves(51)
    only = {"hip_flexion_r": angles["hip_flexion_r"], "knee_angle_l": angles["knee_angle_l"]}
    out = plot_joint_angles(tmp_path / "partial.png", pct, only,
                            events={"toe_off_percent": {"r": None, "l": float("nan")}})
    assert _read_png(out).shape[:2] == EXPECTED_PX
    empty = plot_joint_angles(tmp_path / "empty.png", pct, {})
    assert _read_png(empty).shape[:2] == EXPECTED_PX


def test_plots_with_and_without_curves_differ(tmp_path):
    pct, angles = _curves()
    a = _read_png(plot_joint_angles(tmp_path / "a.png", pct, angles))
    b = _read_png(plot_joint_angles(tmp_path / "b.png", pct, {}))
    assert np.abs(a - b).sum() > 100.0


def test_length_mismatch_raises_one_line_error(tmp_path):
    pct, angles = _curves()
    angles["knee_angle_r"] = angles["knee_angle_r"][:-5]
    with pytest.raises(InputError) as err:
        plot_joint_angles(tmp_path / "bad.png", pct, angles)
    assert "\n" not in str(err.value)
    assert "knee_angle_r" in str(err.value)


def test_no_pyplot_figures_leak(tmp_path):
    import matplotlib.pyplot as plt

    before = plt.get_fignums()
    pct, angles = _curves()
    for i in range(3):
        plot_joint_angles(tmp_path / f"p{i}.png", pct, angles)
    assert plt.get_fignums() == before


def test_a_trip_stages_objective_plot_shows_its_trips_not_the_time_walked(tmp_path,
                                                                          monkeypatch):
    """``plot_objective``: a walking fit's lower panel is the best's time walked; a trip
    stage's (whose best walks its whole walk in every generation) the best's trips
    recovered and taken as people do, of the stage's trips."""
    import matplotlib.pyplot as plt

    from stumble.viz import reflex_plots

    figs, close = [], plt.close
    monkeypatch.setattr(reflex_plots.plt, "close", lambda fig: figs.append(fig))

    def history(trips):
        terms = {"walked_s": 10.0}
        if trips:
            terms.update({f"trip_{s}_1.2": 20.0 for s in (0.1, 0.3, 0.6)},
                         trips_recovered=1, trips_human_strategy=2)
        return [{"generation": g, "best": 10.0 - g, "generation_best": 10.0 - g,
                 "generation_median": 12.0 - g, "terms": terms} for g in range(3)]

    reflex_plots.plot_objective(tmp_path / "walk.png", history(False), "walk")
    reflex_plots.plot_objective(tmp_path / "trips.png", history(True), "trips")
    walk_ax, trips_ax = figs[0].axes[1], figs[1].axes[1]
    assert walk_ax.get_ylabel() == "best walks (s)"
    assert trips_ax.get_ylabel() == "best's trips (of 3)"
    assert [t.get_text() for t in trips_ax.get_legend().get_texts()] == [
        "recovered", "human strategy (window trips)"]
    assert list(trips_ax.lines[0].get_ydata()) == [1, 1, 1]
    for f in figs:
        close(f)
    assert (tmp_path / "trips.png").stat().st_size > 10_000


def test_trip_plot_draws_the_foot_path_of_the_recovery_not_the_walk_on(tmp_path,
                                                                       monkeypatch):
    """trajectories.png: the foot path panel spans the first FOOT_PATH_S (1.5 s) after the
    trip (SCA 2009 Fig. 10's recovery); the angle panels the whole run (6 s walking on
    would flatten a whole-run path to a line)."""
    import stumble.viz.trip_plots as tp
    from stumble.body import build

    model = build().model
    t = np.arange(0.0, 6.0, 0.004)
    qpos = np.repeat(model.qpos0[None], len(t), axis=0)
    seen = []

    def foot_path(m, q, side):
        seen.append(len(q))
        return np.zeros((len(q), 3))

    monkeypatch.setattr(tp, "foot_com_path", foot_path)
    out = tp.plot_trajectories(tmp_path / "t.png", model, t, qpos, "l", "elevating",
                               [("passive_reaction", 0.0)])
    assert tp.FOOT_PATH_S == 1.5 and seen == [int(np.sum(t <= 1.5))] and seen[0] < len(t)
    width = mpimg.imread(out).shape[1]
    assert width > 1000
    # with the body's angular momentum, a fifth panel (the figure a quarter wider)
    out = tp.plot_trajectories(tmp_path / "a.png", model, t, qpos, "l", "elevating",
                               [("passive_reaction", 0.0)], angmom=np.sin(t),
                               contact=(0.0, 0.06))
    assert mpimg.imread(out).shape[1] == pytest.approx(1.25 * width, rel=0.02)


def test_fall_rate_plots_a_scale_where_every_run_falls_and_one_where_none_does(tmp_path):
    """The 95 % Wilson interval at 0 of n and n of n holds its proportion exactly (no
    negative error bar from rounding: 6 of 6 gave -1.1e-16, which Matplotlib refuses)."""
    from stumble.viz.study_plots import plot_fall_rate, wilson_interval

    for n in range(1, 120):
        assert wilson_interval(0, n)[0] == 0.0 and wilson_interval(n, n)[1] == 1.0
    lo, hi = wilson_interval(3, 10)
    assert lo == pytest.approx(0.1078, abs=1e-4) and hi == pytest.approx(0.6032, abs=1e-4)
    rows = [{"controller": "gh2010", "mechanism": "obstacle", "swing_fraction": 0.1 * i,
             "speed_m_per_s": 1.2, "delay_scale": k, "fell": k == 2.0,
             "recovered": k != 2.0, "strategy": "elevating"}
            for k in (1.0, 2.0) for i in range(1, 7)]
    path = plot_fall_rate(tmp_path / "fall_rate.png", rows, ["delay_scale"])
    assert path.read_bytes()[:4] == b"\x89PNG"
    # the response's delays alone (``Scenario.delays``) are a line of their own
    from stumble.viz.study_plots import Tally

    both = rows + [{**r, "delays": "response", "fell": True, "recovered": False}
                   for r in rows]
    lines = set(Tally.of(both).fall)  # (axis, controller, mechanism, delays, the others)
    assert lines == {("delay_scale", "gh2010", "obstacle", "all", None, None),
                     ("delay_scale", "gh2010", "obstacle", "response", None, None)}
    plot_fall_rate(tmp_path / "both.png", both, ["delay_scale"])


def test_fall_rate_over_obstacle_heights_and_not_over_a_force_trips_none(tmp_path):
    """The obstacle height is a fall-rate axis when it takes two values; a force trip's
    height (None) beside one obstacle height is not a second value."""
    from stumble.viz.study_plots import Tally, write_study_plots

    rows = [{"controller": "reflex", "mechanism": "obstacle", "swing_fraction": 0.1 * i,
             "speed_m_per_s": 1.2, "obstacle_height_m": h, "delay_scale": 1.0,
             "strength_scale": 1.0, "fell": h > 0.1 and i > 2, "recovered": not (
                 h > 0.1 and i > 2), "strategy": "elevating"}
            for h in (0.08, 0.10, 0.12) for i in range(1, 7)]
    t = Tally.of(rows)
    assert t.varying_scales() == ["obstacle_height_m"]
    by_h = t.fall[("obstacle_height_m", "reflex", "obstacle", "all", 1.0, 1.0)]
    assert {h: tuple(v) for h, v in by_h.items()} == {0.08: (0, 6), 0.10: (0, 6),
                                                       0.12: (4, 6)}
    assert write_study_plots(tmp_path, t) == ["strategy_map.png", "outcome_map.png",
                                              "fall_rate.png"]
    force = [{**r, "mechanism": "force", "obstacle_height_m": None} for r in rows
             if r["obstacle_height_m"] == 0.10]
    one = Tally.of(force + [r for r in rows if r["obstacle_height_m"] == 0.10])
    assert one.varying_scales() == []
    # a height whose every trip was not set is no value of the axis
    unset = [{**r, "obstacle_height_m": 0.14, "not_set": True, "fell": False,
              "recovered": False} for r in rows if r["obstacle_height_m"] == 0.10]
    assert Tally.of(unset + [r for r in rows if r["obstacle_height_m"] == 0.10]
                    ).varying_scales() == []
    # a delay scale and the height together, force trips beside: two panels, each line
    # named by the other axis (the height in m, none for the force trips)
    from stumble.viz.study_plots import _other_label, plot_fall_rate

    mixed = [{**r, "delay_scale": k} for r in rows + force for k in (1.0, 1.5)]
    t2 = Tally.of(mixed)
    assert t2.varying_scales() == ["delay_scale", "obstacle_height_m"]
    assert ("obstacle_height_m", "reflex", "force", "all", 1.0, 1.0) not in t2.fall
    assert {k[1:3] + k[4:] for k in t2.fall if k[0] == "delay_scale"} == {
        ("reflex", "obstacle", 1.0, h) for h in (0.08, 0.10, 0.12)} | {
        ("reflex", "force", 1.0, None)}
    assert _other_label("obstacle_height_m", 0.08) == ", box 0.08 m"
    assert _other_label("obstacle_height_m", None) == ""
    assert _other_label("delay_scale", 1.5) == ", delay ×1.5"
    png = plot_fall_rate(tmp_path / "two.png", t2, t2.varying_scales())
    assert png.read_bytes()[:4] == b"\x89PNG"


@pytest.mark.parametrize(("sd_deg", "listed"), [(0.0, False), (0.3, False), (2.0, True)])
def test_an_sd_band_too_narrow_to_see_is_neither_drawn_nor_listed(tmp_path, monkeypatch,
                                                                   sd_deg, listed):
    """A played-back walk repeats itself (SD 0): no invisible ±SD entries in the legend."""
    from matplotlib.figure import Figure

    labels = []
    real = Figure.legend

    def legend(self, handles, names, **kw):
        labels.extend(names)
        return real(self, handles, names, **kw)

    monkeypatch.setattr(Figure, "legend", legend)
    pct, angles = _curves()
    plot_joint_angles(tmp_path / "a.png", pct, angles,
                      spread_deg={k: np.full_like(v, sd_deg) for k, v in angles.items()})
    assert ("right ±SD" in labels) is listed and ("left ±SD" in labels) is listed
    assert "right" in labels and "left" in labels

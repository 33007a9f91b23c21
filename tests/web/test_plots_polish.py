"""Figures a technician can read (issue #28): the error-band chart's labels are ≥ 10 pt (they
were 7), the legends of the clearance, pressure and flex plots sit outside the axes (they
covered curves), and the pressure plot's caption names what its legend shows."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.backends.backend_agg import FigureCanvasAgg
from skisnow.app import plots, service

CASE = {"load_kg": 40, "load_position_mm": -160, "snow_modulus_mpa": 200, "porosity": 0.5}


@pytest.fixture(scope="module")
def answers(catalogue):
    return [
        service.contact(
            catalogue, service.ContactInputs(ski=s, grind="tiny-grind", ski_model="rigid", **CASE)
        )
        for s in ("ski-a", "ski-b")
    ]


def _figure_of(monkeypatch, draw, *args):
    seen = {}

    def keep(fig):
        seen["fig"] = fig
        return ""

    monkeypatch.setattr(plots, "_svg", keep)
    draw(*args)
    fig = seen["fig"]
    FigureCanvasAgg(fig).draw()  # lay out (constrained layout places the legend)
    return fig


def _overlap(a, b) -> bool:
    return a.x0 < b.x1 and b.x0 < a.x1 and a.y0 < b.y1 and b.y0 < a.y1


@pytest.mark.parametrize("draw", [plots.clearance_svg, plots.pressure_svg])
def test_legends_do_not_cover_the_curves(monkeypatch, answers, draw):
    fig = _figure_of(monkeypatch, draw, answers)
    ax = fig.axes[0]
    assert not ax.get_legend(), "a legend inside the axes covers curves"
    (legend,) = fig.legends
    renderer = fig.canvas.get_renderer()
    assert not _overlap(legend.get_window_extent(renderer), ax.get_window_extent(renderer))


def test_flex_plot_legend_is_outside_the_axes(monkeypatch):
    x = np.linspace(-900, 900, 181)
    half = 0.45 * np.exp(-(((x - 80) / 200) ** 2))  # a pocket peaking under the old legend
    answer = {
        "profiles": {
            "positions_mm": x.tolist(),
            "half_weight_gap_mm": half.tolist(),
            "full_weight_gap_mm": (0.6 * half).tolist(),
        },
        "inputs": {"ski": "ski-a", "body_weight_kg": 25, "pocket_position_mm": -80},
        "wax_zone": {"start_mm": -180, "end_mm": 320, "length_mm": 500},
    }
    fig = _figure_of(monkeypatch, plots.flex_profile_svg, answer)
    renderer = fig.canvas.get_renderer()
    (legend,) = fig.legends
    assert not fig.axes[0].get_legend()
    assert not _overlap(legend.get_window_extent(renderer), fig.axes[0].get_window_extent(renderer))


def test_band_chart_labels_are_legible(monkeypatch, answers):
    fig = _figure_of(monkeypatch, plots.band_svg, answers)
    for ax in fig.axes:
        for label in [*ax.get_xticklabels(), *ax.get_yticklabels()]:
            if label.get_text():
                assert label.get_fontsize() >= 10, label.get_text()
        assert ax.title.get_fontsize() >= 10


def test_pressure_caption_names_what_the_legend_shows(monkeypatch, answers):
    fig = _figure_of(monkeypatch, plots.pressure_svg, answers)
    entries = [t.get_text() for t in fig.legends[0].get_texts()]
    caption = dict((k, c) for k, c, _ in plots.PLOTS)["pressure"]
    assert "contact zone" in entries and "load position" in entries
    assert any("90 % band" in e for e in entries)
    for words in ("90 % band", "contact zones", "load position", "load share"):
        assert words in caption


def _whiskers(ax) -> list[tuple[float, float]]:
    """The x-extent of every error bar of ``ax`` (matplotlib draws each as a LineCollection)."""
    from matplotlib.collections import LineCollection

    out = []
    for c in ax.collections:
        if isinstance(c, LineCollection):
            for seg in c.get_segments():
                if seg[0][1] == seg[1][1]:  # the horizontal bar, not the caps
                    out.append((float(min(seg[:, 0])), float(max(seg[:, 0]))))
    return out


def test_band_chart_whiskers_are_the_served_intervals(monkeypatch, answers):
    """The whiskers span band.intervals (v (1 − w) … v / (1 − w_above), w_above = w unless
    band.relative_half_width_above names it), and a band of w_above ≥ 1 (no upper end) is drawn
    with an arrow to the right."""
    fig = _figure_of(monkeypatch, plots.band_svg, answers)
    got = sorted(_whiskers(fig.axes[0]))
    want = sorted(tuple(a["band"]["intervals"]["contact_area_cm2"]) for a in answers)
    assert np.ravel(got) == pytest.approx(np.ravel(want), rel=1e-3)
    for a in answers:  # longer above than below
        lo, hi = a["band"]["intervals"]["contact_area_cm2"]
        v = a["apparent"]["contact_area_cm2"]
        assert hi - v > v - lo

    def widened(below, above):
        b = answers[0]["band"]
        return {
            **answers[0],
            "band": {
                **b,
                "relative_half_width": {**b["relative_half_width"], "apparent_contact_area": below},
                "relative_half_width_above": {"apparent_contact_area": above},
            },
        }

    wide = widened(1.2, 1.2)
    fig = _figure_of(monkeypatch, plots.band_svg, [wide])
    v = wide["apparent"]["contact_area_cm2"]
    assert np.ravel(_whiskers(fig.axes[0])) == pytest.approx([0.0, v])
    markers = [line.get_marker() for line in fig.axes[0].get_lines()]
    assert ">" in markers
    # a band wider below than above (the grid part one-sided on soft snow): each side its own,
    # the lower end at 0 from w = 1 on, an upper end where the width above is < 1
    fig = _figure_of(monkeypatch, plots.band_svg, [widened(1.2, 0.1)])
    assert np.ravel(_whiskers(fig.axes[0])) == pytest.approx([0.0, v / 0.9])
    assert ">" not in [line.get_marker() for line in fig.axes[0].get_lines()]
    fig = _figure_of(monkeypatch, plots.band_svg, [widened(0.2, 0.1)])
    assert np.ravel(_whiskers(fig.axes[0])) == pytest.approx([0.8 * v, v / 0.9])

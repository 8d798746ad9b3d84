import argparse
import json
import re
from html import unescape

import numpy as np
import pytest
from report_helpers import decoded_images, n_colors

from testbench.core.errors import InputError
from testbench.reporting import build_report, write_html_report, write_pdf_report
from testbench.scoring.synthetic import make_synthetic_run


def test_html_is_self_contained_and_ordered(html_report):
    html = html_report.read_text()
    assert "<script" not in html
    # No external resource of any kind: every src/href is inline data or an in-page anchor.
    refs = re.findall(r'(?:src|href)="([^"]*)"', html)
    assert refs and all(r.startswith(("data:", "#")) for r in refs)
    assert "url(" not in html and "@import" not in html
    # Configuration and the pass/fail table come before any figure.
    assert html.index("Configuration") < html.index("Thresholds") < html.index("<img")
    for section in ("navigation", "control", "ismn", "relnav", "formation", "sensors"):
        assert f'id="{section}"' in html


def test_threshold_table_shows_failures_and_missing_keys(html_report):
    html = html_report.read_text()
    assert "FAILED" in html
    row = re.search(r"<tr><td>not\.a\.metric</td>.*?</tr>", html).group(0)
    assert "missing" in row and "FAIL" in row
    row = re.search(r"<tr><td>relnav\.error_m\.max</td>.*?</tr>", html).group(0)
    assert "PASS" in row


def test_embedded_figures_decode_and_are_not_blank(html_report, synthetic_run):
    imgs = decoded_images(html_report.read_text())
    report = build_report(synthetic_run)
    n_figs = sum(len(s.figures) for s in report.sections)
    assert len(imgs) == n_figs >= 10  # trajectory, 2 error panels, CDF, control, ISMN x3, relnav, formation, NIS
    for img in imgs:
        assert img is not None and img.shape[0] > 100 and img.shape[1] > 100
        assert img.std() > 10.0
        assert n_colors(img) > 20


def test_sections_without_data_are_omitted(tmp_path):
    d = make_synthetic_run(tmp_path, np.random.default_rng(1), n_vehicles=1, duration_s=20.0, rate_hz=5.0,
                           with_events=False, with_images=False)
    (d / "events" / "corrections.parquet").unlink()
    html = write_html_report(d).read_text()
    assert 'id="navigation"' in html and "This scenario sets no thresholds" in html
    for absent in ('id="ismn"', 'id="relnav"', 'id="formation"', "Correction consistency (NIS)", "NIS "):
        assert absent not in html
    assert "NEES position" in html  # the filter-consistency table still has the NEES rows
    assert "no map preview" in html


def test_configuration_names_the_wind_the_magnetic_anomaly_the_obstacles_and_the_imagery_credit(tmp_path):
    """What the world adds to the truth (run.json's world) is in the configuration table."""
    d = make_synthetic_run(tmp_path, np.random.default_rng(1), n_vehicles=1, duration_s=10.0, rate_hz=5.0,
                           with_events=False, with_images=False)
    info = json.loads((d / "run.json").read_text())
    info["world"] = {"wind": {"speed_mps": 8.0, "from_deg": 300.0, "turbulence": None},
                     "magnetic_anomaly": {"rms_nT": 300.0, "source_depth_m": 2000.0, "seed": None, "waves": 256},
                     "obstacles": [{"name": "hall", "min_ned_m": [10.0, -5.0, -40.0], "max_ned_m": [20.0, 5.0, 0.0]},
                                   {"name": None, "min_ned_m": [0.0, 0.0, -5.0], "max_ned_m": [1.0, 1.0, 0.0]}],
                     "imagery_credit": "Orthophoto: OpenAerialMap contributors, CC BY 4.0"}
    (d / "run.json").write_text(json.dumps(info))
    html = unescape(write_html_report(d).read_text())
    row = re.search(r"<tr><td>magnetic anomaly</td>.*?</tr>", html).group(0)
    assert "300 nT RMS" in row and "2000 m deep" in row and "the run's own draw" in row
    assert "8 m/s from 300°, no turbulence" in re.search(r"<tr><td>wind</td>.*?</tr>", html).group(0)
    hall = re.search(r"<tr><td>obstacle hall</td>.*?</tr>", html).group(0)
    assert "north 10–20 m, east -5–5 m, 0–40 m above the origin" in hall
    assert re.search(r"<tr><td>obstacle 2</td>", html)
    # the imagery's attribution, which its licence asks for where the report shows it
    assert "OpenAerialMap contributors, CC BY 4.0" in re.search(r"<tr><td>imagery credit</td>.*?</tr>", html).group(0)


def test_the_same_raster_warning_only_where_scenes_were_matched(tmp_path):
    """A world whose imagery is also its reference map warns of optimistic scene-matching
    figures, but only in a run that matched scenes (a swarm renders the imagery, matches nothing)."""
    warning = "same raster the matcher uses"
    for with_events in (True, False):
        d = make_synthetic_run(tmp_path / str(with_events), np.random.default_rng(1), n_vehicles=1, duration_s=10.0,
                               rate_hz=5.0, with_events=with_events, with_images=False)
        info = json.loads((d / "run.json").read_text())
        info["same_raster"] = True
        (d / "run.json").write_text(json.dumps(info))
        html = unescape(write_html_report(d).read_text())
        assert (warning in html) == with_events
        assert ("camera raster = matcher raster" in html) == with_events


def test_pdf_has_every_figure(synthetic_run, tmp_path):
    out = write_pdf_report(synthetic_run, tmp_path / "r.pdf")
    data = out.read_bytes()
    assert data.startswith(b"%PDF")
    pages = len(re.findall(rb"/Type\s*/Page[^s]", data))
    n_figs = sum(len(s.figures) for s in build_report(synthetic_run).sections)
    assert pages >= n_figs + 2  # figures + the first page + the metrics listing


def test_report_command(tmp_path):
    from testbench.commands import report as cmd

    run = make_synthetic_run(tmp_path / "run", np.random.default_rng(2), duration_s=10.0, rate_hz=2.0,
                             with_events=False, with_images=False)
    parser = argparse.ArgumentParser()
    cmd.register(parser.add_subparsers())
    args = parser.parse_args(["report", str(run), "--pdf", "--out", str(tmp_path / "x.html")])
    assert args.handler(args) == 0
    assert (tmp_path / "x.html").stat().st_size > 10_000
    assert (run / "report.pdf").read_bytes().startswith(b"%PDF")
    bad = parser.parse_args(["report", str(tmp_path / "nothing")])
    with pytest.raises(InputError, match="not a run directory"):
        bad.handler(bad)



def test_empty_panels_say_why_and_warn_nothing(tmp_path):
    """A run whose scene matching never produced a fix (its camera looked off the map): the
    fix panel names the reason its attempts gave, and no matplotlib warning ("no artists with
    labels") reaches the terminal."""
    import warnings

    import pandas as pd

    from testbench.reporting.figures_events import ismn_fix_figure
    from testbench.scoring.record_io import load_run

    d = make_synthetic_run(tmp_path, np.random.default_rng(3), n_vehicles=1, duration_s=20.0, rate_hz=5.0,
                           with_images=False)
    path = d / "events" / "ismn.parquet"
    ismn = pd.read_parquet(path)
    ismn["fix"] = ismn["accepted"] = False
    for c in ("fix_north_m", "fix_east_m", "fix_down_m"):
        ismn[c] = np.nan
    ismn["reason"] = "search window off the reference map"
    ismn.to_parquet(path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        item = ismn_fix_figure(load_run(d))
        html = write_html_report(d).read_text()
    notes = [t.get_text() for ax in item.figure.axes for t in ax.texts]
    assert f"no scene-matching fix: search window off the reference map ({len(ismn)} of {len(ismn)} attempts)" in notes
    assert item.figure.axes[0].get_legend() is None
    assert 'id="ismn"' in html


def test_the_fix_panel_shows_the_cloud_share_where_the_world_had_clouds(tmp_path):
    import pandas as pd

    from testbench.reporting.figures_events import ismn_fix_figure
    from testbench.scoring.record_io import load_run

    d = make_synthetic_run(tmp_path, np.random.default_rng(3), n_vehicles=1, duration_s=20.0, rate_hz=5.0,
                           with_images=False)
    assert len(ismn_fix_figure(load_run(d)).figure.axes) == 2  # errors, latency
    path = d / "events" / "ismn.parquet"
    ismn = pd.read_parquet(path)
    ismn["truth_cloud_fraction"] = np.linspace(0.0, 1.0, len(ismn))
    ismn.to_parquet(path)
    item = ismn_fix_figure(load_run(d))
    assert len(item.figure.axes) == 3 and "clouds hide" in item.caption
    assert item.figure.axes[-1].get_ylabel() == "ground hidden by cloud (%)"
    ismn["truth_shadow_fraction"] = np.linspace(0.3, 0.0, len(ismn))
    ismn.to_parquet(path)
    item = ismn_fix_figure(load_run(d))
    assert "clouds' shadows" in item.caption and item.figure.axes[-1].get_ylabel().endswith("in shadow (%)")


def test_gnss_sky_figure_and_summary_where_a_receiver_had_a_sky_model(tmp_path):
    """A record with events/gnss_sky.parquet gets the satellites-in-view figure and the
    nav.gnss_sky figures in its summary; one without has neither."""
    import pandas as pd

    for with_sky in (True, False):
        d = make_synthetic_run(tmp_path / str(with_sky), np.random.default_rng(1), n_vehicles=1, duration_s=10.0,
                               rate_hz=5.0, with_events=False, with_images=False)
        if with_sky:
            vid = json.loads((d / "run.json").read_text())["vehicles"][0]["id"]
            t = np.arange(0.0, 10.0, 0.2)
            seen = np.where((t > 3) & (t < 6), 3, 8)
            pd.DataFrame({"vehicle_id": vid, "t_s": t, "satellites_visible": seen, "satellites_above_mask": 8,
                          "hdop": np.where(seen >= 4, 1.1, np.nan), "vdop": np.where(seen >= 4, 1.6, np.nan),
                          "hdop_open_sky": 1.0, "fix": seen >= 4}).to_parquet(d / "events" / "gnss_sky.parquet")
        html = unescape(write_html_report(d).read_text())
        assert ("GNSS satellites in view" in html) == with_sky
        assert ("nav.gnss_sky.fix_share" in html) == with_sky


def test_boresight_figure_where_a_navigator_estimates_its_cameras_boresight(tmp_path):
    """A record with the boresight columns and run.json's camera truth gets the boresight
    figure (three body axes, one more image), titled per vehicle; one without has none."""
    import pandas as pd

    counts = {}
    for with_b in (True, False):
        d = make_synthetic_run(tmp_path / str(with_b), np.random.default_rng(1), n_vehicles=1, duration_s=10.0,
                               rate_hz=5.0, with_events=False, with_images=False)
        if with_b:
            info = json.loads((d / "run.json").read_text())
            vid = info["vehicles"][0]["id"]
            tel = pd.read_parquet(d / "telemetry.parquet")
            t = tel["t_s"].to_numpy()
            for k, axis in enumerate("xyz"):
                # learnt from 2 s, to within 0.01 deg of the truth (0.5, -0.3, 0.2) deg
                tel[f"nav_boresight_{axis}_rad"] = np.where(t < 2.0, 0.0, np.radians([0.5, -0.3, 0.2][k] + 0.01))
                tel[f"nav_sigma_boresight_{axis}_rad"] = np.radians(np.where(t < 2.0, 0.5, 0.02))
            tel.to_parquet(d / "telemetry.parquet")
            info["camera_boresight_error_deg"] = {vid: {"down": [0.5, -0.3, 0.2]}}
            info["camera_boresight_estimated"] = {vid: "down"}
            (d / "run.json").write_text(json.dumps(info))
        html = unescape(write_html_report(d).read_text())
        assert ("Camera boresight vs time" in html) == with_b
        assert ("nav.camera_boresight.final_error_deg" in html) == with_b
        counts[with_b] = len(decoded_images(html))
    assert counts[True] == counts[False] + 1


def test_time_offset_and_intrinsics_figures_where_a_navigator_estimates_them(tmp_path):
    """A record with the time offset and intrinsics columns and run.json's camera truth gets
    one figure of each (and their final errors in the key metrics); one without has neither."""
    import pandas as pd

    counts = {}
    for with_states in (True, False):
        d = make_synthetic_run(tmp_path / str(with_states), np.random.default_rng(1), n_vehicles=1, duration_s=10.0,
                               rate_hz=5.0, with_events=False, with_images=False)
        if with_states:
            info = json.loads((d / "run.json").read_text())
            vid = info["vehicles"][0]["id"]
            tel = pd.read_parquet(d / "telemetry.parquet")
            t = tel["t_s"].to_numpy()
            learnt = t >= 2.0  # from 2 s, near the truth
            tel["nav_camera_time_offset_s"] = np.where(learnt, 0.031, 0.0)
            tel["nav_sigma_camera_time_offset_s"] = np.where(learnt, 0.004, 0.03)
            for k, value in (("pp_u_px", 0.9), ("pp_v_px", -0.45), ("focal_rel", 0.0012)):
                tel[f"nav_camera_{k}"] = np.where(learnt, value, 0.0)
                tel[f"nav_sigma_camera_{k}"] = np.where(learnt, 0.1 if "pp" in k else 2e-4, 1.0 if "pp" in k else 2e-3)
            tel.to_parquet(d / "telemetry.parquet")
            info["camera_time_offset_s"] = {vid: {"down": 0.03}}
            info["camera_time_offset_estimated"] = {vid: "down"}
            info["camera_intrinsics_error"] = {vid: {"down": {"focal_error_rel": 0.001, "principal_point_error_px": [1.0, -0.5]}}}
            info["camera_intrinsics_estimated"] = {vid: "down"}
            (d / "run.json").write_text(json.dumps(info))
        html = unescape(write_html_report(d).read_text())
        for text in ("Camera time offset vs time", "Camera intrinsics vs time", "nav.camera_time_offset.final_error_ms",
                     "nav.camera_intrinsics.final_principal_point_error_px"):
            assert (text in html) == with_states, text
        counts[with_states] = len(decoded_images(html))
    assert counts[True] == counts[False] + 2

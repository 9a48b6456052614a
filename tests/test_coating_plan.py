"""The coating stage of the main job: `sprayplan plan --simulate / --thickness-um` and `sprayplan simulate`."""

from __future__ import annotations

import json

import numpy as np
import pytest
import trimesh

from sprayplan.cli import main
from sprayplan.coating import choose_spacing_and_speed, load_preset


@pytest.fixture(scope="module")
def planned(testdata, tmp_path_factory):
    out = tmp_path_factory.mktemp("coated")
    part = str(testdata / "meshes" / "reach_curved_part.ply")
    code = main(
        [
            "plan",
            part,
            "--units",
            "m",
            "--region",
            "x > -700",
            "-o",
            str(out),
            "--thickness-um",
            "50",
            "--samples",
            "420",
        ]
    )
    assert code == 0
    return out


def test_thickness_target_chooses_spacing_and_speed(planned):
    data = json.loads((planned / "plan.json").read_text())
    choice = choose_spacing_and_speed(load_preset("seed000_circle"), 50.0, standoff_mm=113.0)
    assert data["settings"]["paths"]["spacing_mm"] == pytest.approx(choice.spacing_mm)
    assert data["settings"]["plan"]["gun_speed_mm_s"] == pytest.approx(choice.speed_mm_s)
    assert data["totals"]["chosen_for_thickness"]["target_um"] == 50.0
    # per-stroke process: spray strokes at the chosen speed and the preset's flow, transfers at flow 0
    strokes = [s for st in data["stations"] for s in st["strokes"]]
    assert all(s["flow_ml_min"] == (200.0 if s["spray_on"] else 0.0) for s in strokes)
    assert all(s["speed_mm_s"] == pytest.approx(choice.speed_mm_s) for s in strokes if s["spray_on"])


def test_film_files_are_written_and_agree(planned):
    report = json.loads((planned / "coating.json").read_text())
    table = np.loadtxt(planned / "thickness.csv", delimiter=",", skiprows=1)
    assert (planned / "thickness.csv").read_text().splitlines()[0] == "x,y,z,thickness_um"
    mesh = trimesh.load(planned / "thickness.ply", process=False)
    ply_thickness = np.asarray(mesh.metadata["_ply_raw"]["vertex"]["data"]["thickness_um"])
    np.testing.assert_allclose(ply_thickness, table[:, 3], rtol=1e-5, atol=1e-4)
    assert report["spec"] == {"target_um": 50.0, "tolerance_um": 5.0, "painted_fraction": 0.1}
    assert report["measuring_points"]["count"] == 420
    # the film's mean lands near the target the speed was chosen for (the part is curved, not a flat panel)
    assert 40.0 < report["painted"]["mean_um"] < 60.0
    assert table[:, 3].min() >= 0.0


def test_simulate_reproduces_the_plans_film(planned, capsys):
    before = json.loads((planned / "coating.json").read_text())
    assert main(["simulate", str(planned), "--samples", "420"]) == 0
    assert "film: mean" in capsys.readouterr().out
    after = json.loads((planned / "coating.json").read_text())
    # the same film from the plan read back, up to plan.json's rounding (0.1 um positions, 1e-7 normals)
    assert after["painted"]["mean_um"] == pytest.approx(before["painted"]["mean_um"], rel=1e-4)
    assert after["painted"]["cv"] == pytest.approx(before["painted"]["cv"], rel=1e-4)


def test_simulate_without_a_plan_fails_cleanly(tmp_path, capsys):
    assert main(["simulate", str(tmp_path)]) == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1 and "plan.json" in err

"""The meshes-against-boxes benchmark's table: ratios per measure, higher-is-better for rates, the issue's targets."""

from fog_gym.experiments.bench.geometry import TARGETS, render_geometry


def test_the_table_gives_each_ratio_and_judges_it_against_its_target():
    boxes = {"day step": {"median": 40.0}, "night step": {"median": 400.0}, "point sensors": {"median": 10.0},
             "RL vector steps/s": {"steps_per_s": 400.0}, "memory": {"peak_mb": 100.0}}
    meshes = {"day step": {"median": 50.0}, "night step": {"median": 640.0}, "point sensors": {"median": 15.0},
              "RL vector steps/s": {"steps_per_s": 280.0}, "memory": {"peak_mb": 120.0}}
    lines = "\n".join(render_geometry({"boxes": boxes, "meshes": meshes})).splitlines()
    rows = {line.split("|")[1].strip(): line for line in lines if line.startswith("| ") and "measure" not in line}
    assert set(rows) == set(TARGETS)
    assert "1.25×" in rows["day step"] and "✓" in rows["day step"]
    assert "1.60×" in rows["night step"] and "✗" in rows["night step"]  # above 1.5×
    assert "0.70×" in rows["RL vector steps/s"] and "✗" in rows["RL vector steps/s"]  # a rate below 0.75×
    assert "1.20×" in rows["memory"] and "✓" in rows["memory"]


def test_the_previous_release_option_refuses_a_folder_that_is_no_checkout_before_any_work(tmp_path, capsys):
    import pytest

    from fog_gym.experiments.bench.geometry import bench_previous, main

    with pytest.raises(SystemExit) as e:
        main(["--quick", "--previous", str(tmp_path)])
    assert e.value.code == 2 and "--previous must be a checkout of fog-gym" in capsys.readouterr().err
    with pytest.raises(ValueError, match="checkout of fog-gym"):
        bench_previous(str(tmp_path), repeats=1, steps=1)

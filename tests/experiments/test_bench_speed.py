"""The speed bench's verdicts on the sums of fog fields come from the ratios measured alternating in one process."""

from __future__ import annotations

from fog_gym.experiments.bench.speed import RATIOS, TARGETS, render_figures


def figures(homogeneous: float, field: float) -> dict:
    return {f"{kind}, {f}": {"unit": "ms", "median": {"this tree": v}}
            for kind in ("step", "LiDAR fog")
            for f, v in (("homogeneous", homogeneous), ("HeightFog + FogBank", field), ("two banks", field))}


def rows_of(lines: list[str]) -> dict[str, list[str]]:
    table = [line for line in "\n".join(lines).splitlines() if line.startswith("|")][2:]
    return {cells[0]: cells[1:] for cells in ([c.strip() for c in line.strip("|").split("|")] for line in table)}


def test_the_sums_rows_take_the_alternating_ratios_over_the_figures_medians():
    # figures measured minutes apart say 2.5x; the ratios measured alternating say 1.4x (step) and 1.9x (LiDAR fog)
    ratios = {name: {"runs": [v], "ratio": v} for name, v in zip(RATIOS, (1.4, 1.4, 1.9, 1.9))}
    rows = rows_of(render_figures(figures(2.0, 5.0), 3, ratios))
    step = rows["step, HeightFog + FogBank / homogeneous (this tree, alternating in one process)"]
    lidar = rows["LiDAR fog, two banks / homogeneous (this tree, alternating in one process)"]
    assert step == ["**1.40×**", f"≤ {TARGETS['step, HeightFog + FogBank']:g}×: met"]
    assert lidar == ["**1.90×**", f"≤ {TARGETS['LiDAR fog, two banks']:g}×: met"]


def test_without_the_ratios_the_sums_rows_fall_back_to_the_figures_medians():
    rows = rows_of(render_figures(figures(2.0, 5.0), 3))
    assert rows["step, two banks / homogeneous (this tree, figures' medians)"] == ["**2.50×**", "≤ 1.5×: not met"]
    assert all(len(cells) == 2 for cells in rows.values())  # a target column for every row (empty but on the sums)


def test_fog_gym_bench_refuses_a_bad_previous_install_or_rounds_before_any_work(capsys):
    import pytest

    from fog_gym.experiments.bench.suite import main

    for argv, match in ((["--previous", "/no/such/checkout"], "--previous must be a checkout of fog-gym"),
                        (["--speed", "--rounds", "0"], "--rounds must be >= 1")):  # fmt: skip
        with pytest.raises(SystemExit) as err:
            main(argv)
        assert err.value.code == 2
        assert match in capsys.readouterr().err

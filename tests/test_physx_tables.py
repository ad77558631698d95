"""tools/physx_tables.py on hand-built results: go2 on flat and stairs, levels 1 and 5, seeds 0 and 1, 5 episodes
per cell in MuJoCo, PyBullet and PhysX, the successes of each (simulator, terrain, level) the same in both seeds."""

from __future__ import annotations

from tests.results_factory import make_results, write_results
from tools.physx_tables import main

SIMULATORS = ("mujoco", "pybullet", "physx")
#: Successes of 5 per (terrain, level) in flat 1, flat 5, stairs 1, stairs 5 order, per simulator.
RECORD_A = {"mujoco": (5, 5, 3, 0), "pybullet": (5, 4, 3, 0), "physx": (5, 3, 1, 0)}  # 65, 60, 45 %
RECORD_B = {"mujoco": (5, 5, 3, 0), "pybullet": (5, 3, 1, 0), "physx": (5, 4, 1, 0)}  # 65, 45, 50 %
RECORD_C = {"mujoco": (5, 5, 3, 0), "pybullet": (5, 4, 3, 0), "physx": (0, 0, 0, 0)}  # 65, 60, 0 %
ORDER = (("flat", 1), ("flat", 5), ("stairs", 1), ("stairs", 5))


def results(successes: dict, checkpoint: str | None = None) -> dict:
    """Results whose cell (simulator, terrain, level) has ``successes[simulator][ORDER index]`` successes of 5."""
    def success(robot, backend, terrain, level, seed, episode):
        return episode < successes[backend][ORDER.index((terrain, level))]

    return make_results(robots=("go2",), backends=SIMULATORS, terrains=("flat", "stairs"), levels=(1, 5),
                        seeds=(0, 1), episodes=5, success=success, checkpoint=checkpoint)


def rows_of(text: str) -> dict[str, list[str]]:
    """Markdown table rows by their first cells joined with '/' (e.g. ``flat/1``), cells stripped."""
    rows = {}
    for line in text.splitlines():
        if line.startswith("| ") and not line.startswith("|---"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            rows[cells[0] if cells[0].startswith("`") else f"{cells[0]}/{cells[1]}"] = cells
    return rows


def test_family_levels_gives_each_family_level_and_simulator_with_its_interval(tmp_path, capsys):
    path = write_results(tmp_path / "a.json", results(RECORD_A))
    assert main(["--family-levels", str(path)]) == 0
    rows = rows_of(capsys.readouterr().out)
    assert set(rows) == {"family/level", "flat/1", "flat/5", "stairs/1", "stairs/5"}
    # 10 of 10 (both seeds) and 0 of 10: no bootstrap spread, so the Wilson interval of the pooled count
    # (10 / (10 + 1.96^2) = 0.722; 1.96^2 / (10 + 1.96^2) = 0.278)
    assert rows["flat/1"][2:] == ["100.0 % [72.2, 100.0]"] * 3
    assert rows["stairs/5"][2:] == ["0.0 % [0.0, 27.8]"] * 3
    assert rows["flat/5"][2] == "100.0 % [72.2, 100.0]"
    assert [cell.split(" %")[0] for cell in rows["flat/5"][3:]] == ["80.0", "60.0"]
    assert [cell.split(" %")[0] for cell in rows["stairs/1"][2:]] == ["60.0", "60.0", "20.0"]
    assert main(["--family-levels", "--levels", "5", str(path)]) == 0
    assert set(rows_of(capsys.readouterr().out)) == {"family/level", "flat/5", "stairs/5"}


def test_per_record_gives_simulators_gaps_lowest_and_the_learned_records_line(tmp_path, capsys):
    (tmp_path / "a").mkdir()
    paths = [write_results(tmp_path / "a" / "results.json", results(RECORD_A, checkpoint="a.pt")),
             write_results(tmp_path / "b.json", results(RECORD_B, checkpoint="b.pt")),
             write_results(tmp_path / "c.json", results(RECORD_C))]  # not learned: left out of the last line
    assert main(["--per-record", *map(str, paths)]) == 0
    out = capsys.readouterr().out
    rows = rows_of(out)
    points = {name: [cell.split(" ")[0] for cell in row[1:7]] + [row[7]] for name, row in rows.items()
              if name.startswith("`")}
    assert points == {"`a`": ["65.0", "60.0", "45.0", "+5.0", "+20.0", "+15.0", "PhysX"],
                      "`b`": ["65.0", "45.0", "50.0", "+20.0", "+15.0", "-5.0", "PyBullet"],
                      "`c`": ["65.0", "60.0", "0.0", "+5.0", "+65.0", "+60.0", "PhysX"]}
    for row in (r for name, r in rows.items() if name.startswith("`")):  # every point inside its interval
        for cell in row[1:7]:
            point, low, high = (float(v) for v in cell.replace("%", "").replace("[", "").replace("]", "")
                                .replace(",", "").split())
            assert low <= point <= high, cell
    assert out.strip().splitlines()[-1] == (
        "Learned records (2): PyBullet − PhysX = +5.0 points on average; PhysX is lower beyond its interval in 1 "
        "and higher in 0 of 2: a policy trained in MuJoCo loses more in PhysX than in PyBullet.")


def test_results_without_physx_cells_are_a_one_line_error(tmp_path, capsys):
    two = make_results(robots=("go2",), backends=("mujoco", "pybullet"), terrains=("flat",), levels=(1,),
                       seeds=(0,), episodes=3)
    path = write_results(tmp_path / "two.json", two)
    assert main(["--per-record", str(path)]) == 2
    assert capsys.readouterr().err == ("physx_tables: two: no standard-grid cells in physx "
                                       "(protocol 1.3 results needed)\n")


def test_the_answer_names_a_direction_only_when_the_separating_records_agree():
    from tools.physx_tables import physx_against_pybullet

    def summary(gap):  # PyBullet − PhysX as [point, low, high]
        return {"learned": True, "gaps": {"pybullet-physx": gap}}

    mixed = [summary([0.03, 0.01, 0.05]), summary([-0.02, -0.04, -0.01]), summary([0.005, -0.01, 0.02])]
    assert physx_against_pybullet(mixed) == (
        "Learned records (3): PyBullet − PhysX = +0.5 points on average; PhysX is lower beyond its interval in 1 "
        "and higher in 1 of 3: a policy trained in MuJoCo does not lose consistently more in either.")
    higher = [summary([-0.02, -0.04, -0.01]), summary([0.01, -0.01, 0.03])]
    assert physx_against_pybullet(higher).endswith("higher in 1 of 2: a policy trained in MuJoCo loses less in "
                                                   "PhysX than in PyBullet.")

"""``bench batch``: certified rho of many files through the command line, as JSON."""

import json

from benchmarks import bench


def test_the_batch_runs_every_file_in_one_process_and_reports_per_file(capsys):
    assert bench.main(["batch", "--files", "3", "--repeats", "1"]) == 0
    report = json.loads(capsys.readouterr().out)
    assert report["benchmark"] == "batch" and report["files"] == 3
    assert report["converged"] == "3/3"  # the three answers of the one run of all files
    closure, files = report["force_closure"].split("/")
    assert files == "3" and 0 <= int(closure) <= 3
    for name in ("one", "all"):
        assert report[name]["wall_s"]["median"] > 0 and report[name]["cpu_s"]["median"] > 0
    assert report["answer_ms"]["all"]["median"] > 0
    assert set(report) >= {"per_file_wall_ms", "per_file_cpu_ms", "load_before", "load_after"}

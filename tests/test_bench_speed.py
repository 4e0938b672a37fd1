"""``pr2-drake bench speed --instructions``: the count it reads and its errors (the timed runs
themselves are benchmarks, not tests)."""

import pytest

from pr2_drake.bench import speed


def test_instruction_count_is_the_totals_line(tmp_path):
    # With the instrumentation switched on and off (--instr-atstart=no), callgrind's
    # "summary:" counts only the last span; "totals:" counts them all.
    out = tmp_path / "callgrind.out"
    out.write_text("version: 1\nevents: Ir\nfn=main\n16 5\nsummary: 0\ntotals: 378587638\n")
    assert speed.callgrind_total(out) == 378587638


def test_an_output_without_totals_is_an_error(tmp_path):
    out = tmp_path / "callgrind.out"
    out.write_text("version: 1\nevents: Ir\n")
    with pytest.raises(speed.BenchError, match="no instruction count"):
        speed.callgrind_total(out)
    with pytest.raises(speed.BenchError, match="no instruction count"):
        speed.callgrind_total(tmp_path / "missing.out")


def test_instructions_without_valgrind_exit_2_naming_it(monkeypatch, capsys):
    monkeypatch.setattr(speed.shutil, "which", lambda name: None)
    rc = speed.main(["--instructions", "--no-baseline", "--workloads", "walking"])
    assert rc == 2
    err = capsys.readouterr().err
    assert "valgrind" in err and "callgrind_control" in err

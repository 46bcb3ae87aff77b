"""docs/guide/own-structure.md runs as written: its Python block writes the files, its TOML blocks
are the job files (named by their first line), and its commands run in order from one folder
(issue 36)."""
import json
import pathlib
import re
import shlex

from akf.cli import main

PAGE = pathlib.Path(__file__).resolve().parents[2] / "docs" / "guide" / "own-structure.md"


def test_the_start_to_finish_page_runs_as_written(tmp_path, monkeypatch, capsys):
    text = PAGE.read_text(encoding="utf-8")
    monkeypatch.chdir(tmp_path)
    (code,) = re.findall(r"```python\n(.*?)```", text, re.S)
    exec(compile(code, str(PAGE), "exec"), {"__name__": "__page__"})
    for block in re.findall(r"```toml\n(.*?)```", text, re.S):
        name = block.splitlines()[0].lstrip("# ").strip()
        (tmp_path / name).write_text(block)
    (commands,) = re.findall(r"```bash\n(.*?)```", text, re.S)
    printed = []
    for line in commands.strip().splitlines():
        argv = shlex.split(line)
        assert argv[0] == "akf" and main(argv[1:]) == 0, line
        printed.append(capsys.readouterr().out)
    show, estimate = printed[0], printed[1]
    assert "strain:57  extensometer 17-20" in show and "42.42, 82.05, 83.87" in show and "43.05, 83.27, 85.12" in show
    for folder in ("estimate", "calibrated", "place"):
        assert (tmp_path / "own" / folder / "report.html").exists(), folder
    assert (tmp_path / "own" / "estimate" / "fatigue.png").exists()
    fit = json.loads((tmp_path / "own" / "calibrate" / "calibration.json").read_text())
    assert abs(fit["stiffness_factor"] - 1.0) < 0.01 and "40 of the model's 51 modes" in fit["model_note"]
    assert "RMS force error" in estimate and "fatigue" in estimate

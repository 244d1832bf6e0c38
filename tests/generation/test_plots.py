"""`make plots`: every figure is drawn from the generated kernels and written as a PNG."""
import pytest

matplotlib = pytest.importorskip("matplotlib", reason="matplotlib (the 'plots' extra) is not installed; "
                                 "`make test` and `make plots` install it")

from codegen import plots  # noqa: E402


def test_every_figure_is_written_as_a_png(tmp_path):
    written = plots.write_all(tmp_path, dpi=40)
    assert sorted(p.name for p in written) == sorted(f"{name}.png" for name in plots.FIGURES)
    for path in written:
        assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 2000


def test_unknown_figure_is_refused(tmp_path, capsys):
    assert plots.main(["--out", str(tmp_path), "--only", "fig_11"]) == 2
    assert "unknown figure 'fig_11'" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []

"""benchmarks/fold_rerun_rows.py: the rows of a rerun that differ from their kept rows, folded into the block JSONs
(checked as a dry run: nothing is written)."""
import json

from conftest import bench_module


def test_a_kept_block_reread_differs_nowhere(tmp_path, capsys):
    fold = bench_module("fold_rerun_rows")
    src = fold.ROOT / "benchmarks" / "results" / "diagnose_testbench_loop_heldout12700.json"
    fold.main([str(src), "--dry-run"])
    assert "0 rows differ, in 0 block JSONs (dry run)" in capsys.readouterr().out


def test_a_changed_row_is_found_and_its_tables_named(tmp_path):
    fold = bench_module("fold_rerun_rows")
    d = json.loads((fold.ROOT / "benchmarks" / "results" / "diagnose_testbench_loop_heldout12700.json").read_text())
    row = dict(d["rows"][0], got="stribeck", correct=False, wrong=["stribeck"])
    p = tmp_path / "rerun.json"
    p.write_text(json.dumps({"rows": [row, d["rows"][1]]}))
    changes = fold.differing_rows([p])
    assert list(changes) == [(row["family"], row["robot"], row["k"])]
    files = fold.fold(changes, dry_run=True)
    assert files == {"diagnose_testbench_loop_heldout12700.json": [row["k"]]}
    # the docs' tables are up to date with the kept JSONs: a dry run on them changes nothing
    assert fold.update_tables(files, "label", dry_run=True) == []

"""The Python API page runs: every code block of docs/python.md, in order."""

import re
from pathlib import Path

PAGE = Path(__file__).parents[1] / "docs" / "python.md"


def test_every_code_block_of_the_python_page_runs(capsys):
    blocks = re.findall(r"```python\n(.*?)```", PAGE.read_text(), flags=re.S)
    assert len(blocks) >= 6
    namespace = {}
    for k, block in enumerate(blocks):
        exec(compile(block, f"{PAGE.name} block {k + 1}", "exec"), namespace)  # noqa: S102 (our own docs)
    out = capsys.readouterr().out
    assert "limit" in out and "EA" in out


def test_a_run_without_a_folder_keeps_its_files_while_the_result_lives():
    import shellform as sf

    result = sf.run("von_mises")
    folder = result.folder
    assert (folder / "summary.json").is_file() and result.table()["step"][0] == 0
    del result
    import gc

    gc.collect()
    assert not folder.exists()

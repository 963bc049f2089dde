"""Regenerate the reference section of docs/scenes.md from the scene schema.

    python docs/update_reference.py
"""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))  # the checkout, whether installed or not

from shellform.scene.schema import reference  # noqa: E402
from shellform.scene.format import SCENE  # noqa: E402

MARK = "This section is generated from the schema (`shellform schema` prints it).\n"

path = Path(__file__).with_name("scenes.md")
text = path.read_text()
head = text[: text.index(MARK) + len(MARK)]
path.write_text(head + "\n" + reference(SCENE) + "\n")

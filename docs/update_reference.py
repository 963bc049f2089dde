"""Regenerate the reference section of docs/scenes.md from the scene schema.

    python docs/update_reference.py
"""

from pathlib import Path

from shellform.schema import describe
from shellform.scene import SCENE

MARK = "This section is generated from the schema (`shellform schema` prints it).\n"

path = Path(__file__).with_name("scenes.md")
text = path.read_text()
head = text[: text.index(MARK) + len(MARK)]
path.write_text(head + "\n" + "\n".join(describe(SCENE, level=3)) + "\n")

"""Write firmware_proto/test_vectors.json (golden frames shared by the C and Python tests).

Run ``python firmware_proto/gen_vectors.py``; the output is committed and only changes
when messages.yaml changes (the generator is seeded).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parent))

from guardid.protocol.vectors import golden_vectors  # noqa: E402

OUT = HERE / "test_vectors.json"


def render() -> str:
    """The JSON text of the vectors."""
    return json.dumps(golden_vectors(), indent=1) + "\n"


if __name__ == "__main__":
    OUT.write_text(render(), encoding="utf-8")
    print(f"wrote {OUT.relative_to(HERE.parent)}")

"""Generate firmware_proto/avr/robot_config.h from the robot YAML (default: guard).

``python firmware_proto/avr/gen_robot.py [ROBOT]`` writes the header; ``--check`` only
compares and exits 1 when it is stale. ROBOT is a shipped robot name or a YAML path.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from guardid.firmware.avr_sim.robot_header import HEADER, render  # noqa: E402
from guardid.robot import load_robot  # noqa: E402
from guardid.robot.loader import shipped_path  # noqa: E402


def main(argv: list[str]) -> int:
    check = "--check" in argv
    args = [a for a in argv if a != "--check"]
    robot = args[0] if args else "guard"
    path = Path(robot) if Path(robot).suffix in (".yaml", ".yml") else shipped_path(robot)
    try:
        source = str(path.resolve().relative_to(ROOT))
    except ValueError:
        source = path.name
    text = render(load_robot(str(path)), source)
    if check:
        if not HEADER.is_file() or HEADER.read_text() != text:
            print(f"{HEADER} is stale: run python firmware_proto/avr/gen_robot.py", file=sys.stderr)
            return 1
        return 0
    HEADER.write_text(text)
    print(f"wrote {HEADER}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

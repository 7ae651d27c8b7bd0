"""The tables of ``docs/nodes.md`` generated from the nodes' own tables (:data:`.params.PARAMS`,
:data:`.interfaces.CALIBRATION_NODE_INTERFACES` and ``STEREO_NODE_INTERFACES``, ``replay_node.PARAMS``,
``publisher_node.PARAMS``).

``python -m pascal_calib_ros.ros.docs [--check] [docs/nodes.md]`` rewrites every block between
``<!-- generated: NAME -->`` and ``<!-- end generated -->``; with ``--check`` it only says whether the
page is up to date (exit code 1 when it is not).
"""

from __future__ import annotations

import argparse
import re
import sys
from pathlib import Path
from typing import Any

from .interfaces import CALIBRATION_NODE_INTERFACES, STEREO_NODE_INTERFACES, Interface
from .params import PARAMS, READ_ONLY, Param

PAGE = Path(__file__).resolve().parents[2] / "docs" / "nodes.md"
BLOCK = re.compile(r"(<!-- generated: (?P<name>[\w-]+) -->\n)(?P<body>.*?)(<!-- end generated -->)", re.S)


def _value(v: Any) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    return f"`{v!r}`".replace("'", '"') if isinstance(v, str) else f"{v}"


def _meaning(p: Param) -> str:
    extra = []
    if p.choices:
        extra.append("one of " + ", ".join(f"`{c}`" if c else '`""`' for c in p.choices))
    if p.int_range or p.float_range:
        lo, hi = p.int_range or p.float_range  # type: ignore[misc]
        extra.append(f"range {lo:g} to {hi:g}")
    if p.name in READ_ONLY:
        extra.append("read only")
    if p.modes != ("mono", "stereo"):
        extra.append(f"{p.modes[0]} only")
    return p.description + (f" ({'; '.join(extra)})" if extra else "")


def calibration_node_parameters() -> str:
    rows = ["| parameter | default | meaning |", "|---|---|---|"]
    rows += [f"| `{p.name}` | {_value(p.default)} | {_meaning(p)} |" for p in PARAMS]
    return "\n".join(rows) + "\n"


def _interfaces(table: tuple[Interface, ...]) -> str:
    rows = ["| interface | type | what |", "|---|---|---|"]
    rows += [f"| `{i.name}` ({i.kind}) | {i.type} | {i.description} |" for i in table]
    return "\n".join(rows) + "\n"


def calibration_node_interfaces() -> str:
    return _interfaces(CALIBRATION_NODE_INTERFACES)


def stereo_node_interfaces() -> str:
    return _interfaces(STEREO_NODE_INTERFACES)


def _simple_parameters(table: tuple[tuple[str, Any, str], ...]) -> str:
    rows = ["| parameter | default | meaning |", "|---|---|---|"]
    rows += [f"| `{name}` | {_value(default)} | {desc} |" for name, default, desc in table]
    return "\n".join(rows) + "\n"


def replay_node_parameters() -> str:
    from .replay_node import PARAMS as REPLAY_PARAMS

    return _simple_parameters(REPLAY_PARAMS)


def publisher_parameters() -> str:
    from .publisher_node import PARAMS as PUBLISHER_PARAMS

    return _simple_parameters(PUBLISHER_PARAMS)


TABLES = {"calibration-node-interfaces": calibration_node_interfaces,
          "calibration-node-stereo-interfaces": stereo_node_interfaces,
          "calibration-node-parameters": calibration_node_parameters,
          "replay-node-parameters": replay_node_parameters,
          "publisher-parameters": publisher_parameters}


def render(text: str) -> str:
    """``text`` with every generated block replaced by its table; an unknown block name is an error."""
    def fill(m: re.Match[str]) -> str:
        name = m.group("name")
        if name not in TABLES:
            raise KeyError(f"unknown generated block {name!r}; known: {', '.join(TABLES)}")
        return m.group(1) + TABLES[name]() + m.group(4)

    return BLOCK.sub(fill, text)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description="generate the node tables of docs/nodes.md")
    ap.add_argument("page", nargs="?", default=str(PAGE))
    ap.add_argument("--check", action="store_true", help="only check that the page is up to date")
    a = ap.parse_args(argv)
    page = Path(a.page)
    text = page.read_text()
    new = render(text)
    if a.check:
        if new != text:
            print(f"{page} is stale: run python -m pascal_calib_ros.ros.docs", file=sys.stderr)
            return 1
        print(f"{page} is up to date")
        return 0
    page.write_text(new)
    print(f"wrote {page}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

"""Read YAML as people write it: ``5e-2`` is a number, and a key given twice is an error.

PyYAML follows YAML 1.1, where a float needs a dot (``5.0e-2``): ``5e-2`` and ``1e3`` came out as strings,
and a rig option written so was refused as "not a number". YAML 1.2 (and JSON, and every other tool) reads
them as numbers. A mapping that names a key twice (``frame 0:`` listed twice in a ground-truth file) kept
the last one silently; here it is an error naming the line.
"""

from __future__ import annotations

import re
from typing import Any

import yaml

__all__ = ["load_yaml", "yaml_problem"]

_Base: Any = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


class _Loader(_Base):
    def construct_mapping(self, node: yaml.MappingNode, deep: bool = False) -> dict[Any, Any]:
        seen: set[Any] = set()
        for key_node, _ in node.value:
            key = self.construct_object(key_node, deep=True)
            try:
                duplicate = key in seen
            except TypeError:  # an unhashable key: the constructor itself refuses it
                continue
            if duplicate:
                raise yaml.constructor.ConstructorError(
                    "while reading a mapping",
                    node.start_mark,
                    f"the key {key!r} is given twice",
                    key_node.start_mark,
                )
            seen.add(key)
        return dict(super().construct_mapping(node, deep=deep))


_Loader.add_implicit_resolver(
    "tag:yaml.org,2002:float",
    re.compile(r"^[-+]?(?:[0-9][0-9_]*(?:\.[0-9_]*)?|\.[0-9_]+)[eE][-+]?[0-9]+$"),
    list("-+0123456789."),
)


def load_yaml(text: str) -> Any:
    """``yaml.safe_load`` with YAML 1.2's exponent floats and duplicate keys refused.

    Raises:
        yaml.YAMLError: invalid YAML, or a key given twice in one mapping (with its line in
            ``problem_mark``).
    """
    return yaml.load(text, Loader=_Loader)


def yaml_problem(exc: yaml.YAMLError) -> str:
    """What is wrong in a YAML error, and where: ``"the key 'frame 0' is given twice (line 4, column 1)"``."""
    mark = getattr(exc, "problem_mark", None)
    where = f" (line {mark.line + 1}, column {mark.column + 1})" if mark is not None else ""
    return f"{getattr(exc, 'problem', None) or 'invalid YAML'}{where}"

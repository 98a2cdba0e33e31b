"""Stone Soup YAML configurations may name jointtrack's components.

Stone Soup's :class:`stonesoup.serialise.YAML` writes any component with the tag
``!<module>.<class>`` but reads back only tags under ``!stonesoup.``. Importing
:mod:`jointtrack.interop.stonesoup` registers, on ruamel's round-trip
constructor that Stone Soup's YAML uses, the same reader for tags under
``!jointtrack.``: a tracker configuration with ``JPDAExact`` or
``FastPDAHypothesiser`` in it loads like one with Stone Soup's own components.
Only Stone Soup components (subclasses of ``stonesoup.base.Base``) defined in
jointtrack are built; any other tag is an error.
"""

from __future__ import annotations

from importlib import import_module

from ruamel.yaml.constructor import ConstructorError, RoundTripConstructor
from stonesoup.base import Base

__all__ = ["TAG_PREFIX"]

TAG_PREFIX = "!jointtrack."


def _component_from_yaml(constructor, tag_suffix, node):
    """Build the jointtrack Stone Soup component named by ``!jointtrack.<module>.<class>``."""
    module_name, _, class_name = f"jointtrack.{tag_suffix}".rpartition(".")
    try:
        cls = getattr(import_module(module_name), class_name, None)
    except ImportError:
        cls = None
    if not (isinstance(cls, type) and issubclass(cls, Base)):
        raise ConstructorError(
            "while constructing a Stone Soup component",
            node.start_mark,
            f"'jointtrack.{tag_suffix}' is not a jointtrack Stone Soup component",
            node.start_mark,
        )
    # as Stone Soup's own reader: mutable sub-objects must be complete before the call
    constructor.deep_construct = True
    properties = list(constructor.construct_yaml_omap(node))[0]
    try:
        return cls(**properties)
    except Exception as exc:
        raise ConstructorError(
            "while constructing a Stone Soup component", node.start_mark, str(exc), node.start_mark
        ) from exc


RoundTripConstructor.add_multi_constructor(TAG_PREFIX, _component_from_yaml)

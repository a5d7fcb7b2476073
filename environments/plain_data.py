"""Checks shared by the readers of YAML files (scenarios here, robot descriptions in stances).

Each reader has its own error type (with its file); these helpers take the
reader's ``error(key, message)`` factory, so every message names the dotted key
path at fault and says what would be valid.
"""

from __future__ import annotations

from collections.abc import Hashable, Mapping

import yaml

__all__ = ["join_key", "kind_of", "checked_mapping", "load_yaml", "repeated_key"]


def repeated_key(node: yaml.MappingNode) -> tuple[str, int] | None:
    """Why a composed YAML mapping is refused when it gives a key twice (YAML keeps the
    last silently: a stance, an object or a robot surface defined twice would lose its
    first definition unseen), and the second one's line; None if no key repeats.
    ``<<`` (merging a mapping in) may repeat. Keys are compared as YAML builds them:
    ``yes`` and ``true`` are one key (True), as are ``1`` and ``1.0``; ``1`` and
    ``'1'`` are two."""
    constructor = yaml.constructor.SafeConstructor()  # one per mapping: it remembers what it built
    seen: dict = {}
    for key_node, _ in node.value:
        if not isinstance(key_node, yaml.ScalarNode) or key_node.tag == _MERGE:
            continue
        line = key_node.start_mark.line + 1
        key = _built_key(constructor, key_node)
        if key in seen:
            text, first, built = seen[key]
            what = (f"{text!r} is given twice" if text == key_node.value
                    else f"{text!r} and {key_node.value!r} are one key to YAML ({built!r}), given twice")
            return f"{what} (lines {first} and {line}); YAML would keep only the last: remove or rename one", line
        seen[key] = (key_node.value, line, key)
    return None


_MERGE, _VALUE = "tag:yaml.org,2002:merge", "tag:yaml.org,2002:value"


def _built_key(constructor, key_node: yaml.ScalarNode):
    """The key YAML builds from a scalar key node; where it builds none here (a tag
    with no constructor, a key that cannot be a key), the node's tag and text, so that
    building the document itself says what is wrong."""
    if key_node.tag == _VALUE:
        return key_node.value  # a plain '=' key: a string once in a mapping
    try:
        key = constructor.construct_object(key_node)
    except yaml.YAMLError:
        return (key_node.tag, key_node.value)
    return key if isinstance(key, Hashable) else (key_node.tag, key_node.value)


def _mappings(root: yaml.Node):
    """Every mapping node of a composed document, each once (aliases repeat nodes)."""
    stack, visited = [root], set()
    while stack:
        node = stack.pop()
        if id(node) in visited:
            continue
        visited.add(id(node))
        if isinstance(node, yaml.MappingNode):
            yield node
            stack.extend(value for pair in node.value for value in pair)
        elif isinstance(node, yaml.SequenceNode):
            stack.extend(node.value)


def load_yaml(text, inspect=None):
    """``yaml.safe_load``, but a key given twice in one mapping is a
    ``yaml.constructor.ConstructorError`` naming it and its two lines.

    The document is parsed once; its keys are checked on the composed tree, before any
    mapping is built (building merges ``<<`` mappings into their targets' nodes).

    Parameters
    ----------
    text : str
    inspect : callable, optional
        Called with the composed tree's root before anything is built, in place of
        the repeated-key check: a reader that walks the tree anyway (the scenario
        reader, recording each key's line) checks the keys itself with
        :func:`repeated_key` and names their key paths.
    """
    loader = yaml.SafeLoader(text)
    try:
        root = loader.get_single_node()
        if root is None:
            return None
        if inspect is not None:
            inspect(root)
        else:
            for node in _mappings(root):
                repeated = repeated_key(node)
                if repeated is not None:
                    raise yaml.constructor.ConstructorError(None, None, repeated[0], node.start_mark)
        return loader.construct_document(root)
    finally:
        loader.dispose()


def join_key(key: str, name) -> str:
    """Dotted key path of ``name`` inside ``key`` (``"objects[1]"`` + ``"size"``)."""
    return f"{key}.{name}" if key else str(name)


def kind_of(value) -> str:
    """A short description of a value for messages: ``"a mapping"``, ``"a list of 2"``, ``"int 3"``."""
    if value is None:
        return "nothing"
    if isinstance(value, Mapping):
        return "a mapping" if value else "an empty mapping"
    if isinstance(value, list):
        return f"a list of {len(value)}" if value else "an empty list"
    return f"{type(value).__name__} {value!r}"


def checked_mapping(value, key: str, allowed, required, error) -> dict:
    """A mapping with only ``allowed`` keys and every ``required`` one, as a dict.

    Parameters
    ----------
    value : object
        The YAML value.
    key : str
        Its dotted key path.
    allowed, required : sequence of str
        Valid keys, and those that must be present.
    error : callable
        ``error(key, message)`` returns the exception to raise.

    Raises
    ------
    Exception
        What ``error`` returns, for a non-mapping, an unknown or a missing key.
    """
    if not isinstance(value, Mapping):
        raise error(key, f"must be a mapping with keys {', '.join(allowed)}; got {kind_of(value)}")
    for name in value:
        if name not in allowed:
            raise error(join_key(key, name), f"unknown key {name!r}; valid keys: {', '.join(allowed)}")
    for name in required:
        if name not in value:
            raise error(key, f"missing key {name!r}")
    return dict(value)

"""A Griffe extension for the API reference: hsr's docstrings use Sphinx roles
(:func:`hsr.render`, :class:`~hsr.errors.MeshError`) and reStructuredText literals
(``x``), which Markdown would show as typed. Each becomes inline code naming the object
(the last part when the role starts with ``~``, as Sphinx shows it)."""

from __future__ import annotations

import re

import griffe

ROLE = re.compile(r":(?:py:)?(?:func|class|meth|mod|data|attr|exc|obj):`(~?)([^`]+)`")


def _markdown(text: str) -> str:
    text = ROLE.sub(lambda m: f"`{m.group(2).rsplit('.', 1)[-1] if m.group(1) else m.group(2)}`",
                    text)
    return text.replace("``", "`")


class Roles(griffe.Extension):
    def on_object(self, *, obj, **kwargs) -> None:
        if obj.docstring is not None:
            obj.docstring.value = _markdown(obj.docstring.value)

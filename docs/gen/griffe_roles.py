"""Griffe extension: parmpm's docstrings as the API pages' Markdown.

* Sphinx roles (``:mod:`x```, ``:func:`y```): mkdocstrings renders Markdown, where a role would
  show itself. Each becomes a cross-reference ``[`x`][path]`` when its target is an object the
  API pages render (public, documented), looked up from the object's own scope outwards as
  Sphinx does; any other role becomes plain code. A role never breaks the strict build.
* Indentation: Python's ``cleandoc`` removes the common indent of the lines after the first, so
  a module docstring whose body is one indented example loses the indent that made it a code
  block. The docstring is dedented by the column of its opening quotes instead (the same result
  for every docstring written the usual way).
* reST simple tables (columns under ``=====  =====`` borders) become Markdown tables, and a
  paragraph ending in ``::`` (reST's "a literal block follows") ends in ``:``.
"""

from __future__ import annotations

import re

import griffe

BORDER = re.compile(r"^(=+)( +=+)+ *$")
ROLE = re.compile(r":(?:mod|func|class|data|meth|attr|obj|exc|const):`(~?)([\w.]+)(?:\(\))?`")


def _rendered(obj) -> bool:
    """Whether the API pages render ``obj`` (so an anchor exists for a link)."""
    try:
        while obj.is_alias:
            obj = obj.final_target
    except Exception:  # an alias to something not loaded: no page has it
        return False
    if any(part.startswith("_") and part not in ("__init__", "__main__")
           for part in obj.path.split(".")):
        return False
    return obj.is_module or bool(obj.docstring)


def _lookup(scope, dotted: str):
    head, *rest = dotted.split(".")
    while scope is not None:
        if head in scope.members:
            obj = scope.members[head]
            try:
                for part in rest:
                    obj = obj.members[part]
            except (KeyError, Exception):
                return None
            return obj
        scope = scope.parent
    return None


def _columns(border: str) -> list[tuple[int, int]]:
    return [m.span() for m in re.finditer(r"=+", border)]


def _cells(line: str, spans) -> list[str]:
    cells = []
    for i, (start, _) in enumerate(spans):
        end = spans[i + 1][0] if i + 1 < len(spans) else len(line)
        cells.append(line[start:end].strip())
    return cells


def rst_tables(text: str) -> str:
    """reST simple tables as Markdown tables (a row whose first cell is empty continues the row
    above); a table without a header row gets an empty one, as Markdown needs one."""
    lines, out, i = text.split("\n"), [], 0
    while i < len(lines):
        if not BORDER.match(lines[i]):
            out.append(lines[i])
            i += 1
            continue
        spans, rows, borders, j = _columns(lines[i]), [], [i], i + 1
        while j < len(lines) and len(borders) < 3:
            if BORDER.match(lines[j]):
                borders.append(j)
                if j + 1 >= len(lines) or not lines[j + 1].strip():
                    break
            elif lines[j].strip():
                cells = _cells(lines[j], spans)
                if rows and not cells[0]:
                    rows[-1] = [f"{a} {b}".strip() for a, b in zip(rows[-1], cells)]
                else:
                    rows.append(cells)
            j += 1
        header = rows.pop(0) if len(borders) == 3 and rows else [""] * len(spans)
        out += ["| " + " | ".join(header) + " |", "|" + "---|" * len(spans)]
        out += ["| " + " | ".join(c.replace("|", "\\|") for c in row) + " |" for row in rows]
        i = j + 1
    text = "\n".join(out)
    return re.sub(r"(\S)::\n\n", r"\1:\n\n", text)


def _dedent_by_quotes(obj) -> str | None:
    """The docstring as written, dedented by the column of its opening quotes (None: unchanged)."""
    doc = obj.docstring
    try:
        lines = obj.lines_collection[obj.filepath][doc.lineno - 1:doc.endlineno]
    except Exception:
        return None
    if not lines:
        return None
    first = lines[0]
    col = len(first) - len(first.lstrip())
    opening = first.lstrip()
    if not opening.startswith('"""') or not lines[-1].rstrip().endswith('"""'):
        return None
    body = [opening[3:]] + [line[col:] if line[:col].strip() == "" else line.lstrip()
                            for line in lines[1:]]
    text = "\n".join(body).rstrip()
    text = text[:-3] if text.endswith('"""') else text
    text = text.strip("\n").rstrip()
    # only where the usual cleaning lost an indent; everything else stays as griffe read it
    return text if text.strip() != doc.value.strip() and "\n    " in text else None


class SphinxRoles(griffe.Extension):
    def __init__(self) -> None:
        self._pending: list = []

    def on_package(self, *, pkg, loader, **kwargs) -> None:
        for name in ("parmpm", "decomposition"):  # cross-package roles need both loaded
            if name not in loader.modules_collection.members:
                try:
                    loader.load(name)
                except Exception:
                    pass
        collection = loader.modules_collection
        self._rewrite(pkg, collection)

    def _rewrite(self, obj, collection) -> None:
        if obj.is_alias:
            return
        if obj.docstring is not None:
            obj.docstring.value = rst_tables(_dedent_by_quotes(obj) or obj.docstring.value)
            obj.docstring.value = ROLE.sub(lambda m: self._link(m, obj, collection),
                                           obj.docstring.value)
        for member in obj.members.values():
            if not member.is_alias:
                self._rewrite(member, collection)

    @staticmethod
    def _link(match, obj, collection) -> str:
        tilde, target = match.groups()
        shown = target.rpartition(".")[2] if tilde else target
        found = _lookup(obj, target)
        if found is None:
            try:
                found = collection.get_member(target) if "." in target else \
                    collection.members.get(target)
            except Exception:
                found = None
        if found is None or not _rendered(found):
            return f"`{shown}`"
        path = found.final_target.path if found.is_alias else found.path
        return f"[`{shown}`][{path}]"

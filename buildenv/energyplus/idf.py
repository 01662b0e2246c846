"""Reading, editing and writing EnergyPlus IDF text (for models we did not write: the DOE reference buildings).

An IDF is a list of objects; each object here is a list of strings ``[type, field1, field2, ...]``, comments
dropped. Types compare case-insensitively, as EnergyPlus does. Only what editing a reference building
needs is provided: find objects by type or name, replace an object, append objects, write the text back.
"""

from __future__ import annotations

from pathlib import Path

IdfObject = list[str]


def parse_idf(text: str) -> list[IdfObject]:
    """Split IDF text into objects ``[type, field1, ...]`` (``!`` comments dropped, fields stripped)."""
    body = "\n".join(line.split("!", 1)[0] for line in text.splitlines())
    return [[f.strip() for f in chunk.split(",")] for chunk in body.split(";") if chunk.strip()]


def read_idf(path: str | Path) -> list[IdfObject]:
    """Parse an IDF file."""
    return parse_idf(Path(path).read_text(errors="replace"))


def format_idf(objects: list[IdfObject]) -> str:
    """IDF text of ``objects``, one field per line."""
    return "\n".join(",\n    ".join(o) + ";\n" for o in objects)


def of_type(objects: list[IdfObject], kind: str) -> list[IdfObject]:
    """Objects of one type (case-insensitive)."""
    kind = kind.lower()
    return [o for o in objects if o[0].lower() == kind]


def without(
    objects: list[IdfObject],
    kinds: set[str] | None = None,
    names: set[str] | None = None,
    name_kinds: set[str] | None = None,
) -> list[IdfObject]:
    """Objects minus those of ``kinds`` and those whose name (field 1) is in ``names`` (case-insensitive),
    the latter restricted to types in ``name_kinds`` when given."""
    kinds = {k.lower() for k in kinds or ()}
    names = {n.lower() for n in names or ()}
    name_kinds = {k.lower() for k in name_kinds} if name_kinds else None
    out = []
    for o in objects:
        kind = o[0].lower()
        if kind in kinds:
            continue
        if len(o) > 1 and o[1].lower() in names and (name_kinds is None or kind in name_kinds):
            continue
        out.append(o)
    return out

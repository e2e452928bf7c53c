"""BibTeX for ``CITATION.cff``: the software and each paper in its ``references``.

``cffconvert -f bibtex`` converts the software alone, under the key ``YourReferenceHere``; the citing page and
every environment page show these entries instead, so ``CITATION.cff`` stays the one place a citation is written.
An entry holds what the CFF entry holds (authors, title, journal, volume, issue, year): a paper that states no venue
or year is a ``@misc`` without them, nothing filled in from elsewhere.
"""

from __future__ import annotations

import re
from pathlib import Path

#: CFF reference field -> BibTeX field, in the order an entry lists them (after author and title).
_VENUE_FIELDS = {"journal": "journal", "volume": "volume", "issue": "number", "year": "year"}


def load_citation(path: Path) -> dict:
    """``CITATION.cff`` as a dict (YAML; pyyaml comes with myst-parser in the docs extra and with the dev extra)."""
    import yaml

    return yaml.safe_load(Path(path).read_text(encoding="utf-8"))


def bibtex_authors(authors: list[dict]) -> str:
    """``Family, Given and Family, Given``; an entity (``name:``) in braces, so that BibTeX keeps it whole."""
    names = []
    for author in authors:
        if "family-names" in author:
            given = author.get("given-names")
            names.append(f"{author['family-names']}, {given}" if given else author["family-names"])
        else:
            names.append(f"{{{author['name']}}}")
    return " and ".join(names)


def citation_key(reference: dict) -> str:
    """Google Scholar's style: the first author's family name, the year if stated, the title's first word."""
    first = reference["authors"][0]
    name = first.get("family-names", first.get("name", ""))
    word = reference["title"].split()[0]
    return re.sub(r"[^a-z0-9]", "", f"{name}{reference.get('year', '')}{word}".lower())


def _entry(kind: str, key: str, fields: dict[str, object]) -> str:
    lines = [f"@{kind}{{{key},"]
    lines += [f"  {name} = {{{value}}}," for name, value in fields.items() if value is not None]
    return "\n".join([*lines, "}"])


def reference_entry(reference: dict) -> str:
    """One paper of ``references``: ``@article`` where it names its journal, else ``@misc``."""
    fields: dict[str, object] = {
        "author": bibtex_authors(reference["authors"]),
        "title": f"{{{reference['title']}}}",  # braced: BibTeX styles would lower-case "Buckybot", "Platonic"
    }
    fields |= {bib: reference.get(cff) for cff, bib in _VENUE_FIELDS.items()}
    kind = "article" if reference.get("journal") else "misc"
    return _entry(kind, citation_key(reference), fields)


def software_entry(citation: dict) -> str:
    """The software itself: ``@misc`` with its version and the year it was released."""
    fields = {
        "author": bibtex_authors(citation["authors"]),
        "title": f"{{{citation['title']}}}",
        "note": f"Software, version {citation['version']}",
        "year": str(citation["date-released"])[:4],
    }
    return _entry("misc", citation["title"].split(":")[0].lower(), fields)


def bibtex_file(citation: dict) -> str:
    """The software's entry, then every reference's, as one ``.bib`` file."""
    entries = [software_entry(citation), *(reference_entry(r) for r in citation.get("references", []))]
    return "\n\n".join(entries) + "\n"


def find_reference(citation: dict, title: str) -> dict:
    """The reference titled ``title``; ``KeyError`` names it if ``CITATION.cff`` has none."""
    for reference in citation.get("references", []):
        if reference["title"] == title:
            return reference
    raise KeyError(f"CITATION.cff has no reference titled {title!r}")

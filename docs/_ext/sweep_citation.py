"""The citing page, rendered from ``CITATION.cff`` when the site is built.

``{sweep-citation}`` writes how to cite the software (its entry and a BibTeX record)
and ``{sweep-references}`` every entry of the file's ``references`` (the seed paper
first), each with what the package uses it for and a label ``cite-<key>`` that other
pages link to, e.g. ``{ref}`Dieterich (1979) <cite-dieterich1979>```; a BibTeX block
of all of them follows. The file is the one source: edit it, not the page.

The software's year is that of its ``date-released``; until a version is released,
the year of the commit the site is built from (APA's rule for software: the year of
the version used). In the BibTeX records, proper names and acronyms in titles are
braced (``{Lyapunov}``, ``{Rice}--{Ruina}``, ``{II}``) so that styles that set titles
in sentence case keep their capitals, and two names joined by a hyphen are joined by
an en dash, as on the page (Rice–Ruina, Runge–Kutta).
"""

import re
import subprocess
import unicodedata
from pathlib import Path

import yaml
from sphinx.util.docutils import SphinxDirective

ROOT = Path(__file__).resolve().parents[2]
CFF = ROOT / "CITATION.cff"
#: Proper names in the references' titles that are not authors of a reference.
PROPER_NAMES = {"Rice", "Ruina", "Lyapunov", "Hamiltonian", "Runge", "Kutta"}


def read_cff():
    return yaml.safe_load(CFF.read_text(encoding="utf-8"))


def software_year(cff):
    """The year of ``date-released``, else of the commit checked out (the version is
    not released yet), else None."""
    if "date-released" in cff:
        return str(cff["date-released"])[:4]
    try:
        out = subprocess.run(["git", "log", "-1", "--format=%cs"], cwd=ROOT,
                             capture_output=True, text=True, check=True, timeout=10)  # fmt: skip
    except (OSError, subprocess.SubprocessError):
        return None
    return out.stdout.strip()[:4] or None


def proper_names(cff):
    """The names titles keep capitalised: :data:`PROPER_NAMES` and every author's."""
    refs = [cff, *cff.get("references", [])]
    family = {a["family-names"] for r in refs for a in r["authors"] if "family-names" in a}
    return PROPER_NAMES | family


#: A word of a title: letters (any script), with the hyphen or dash that may follow.
WORD = re.compile(r"[^\W\d_]+")


def title_text(title, names):
    """A title for the page: two proper names joined by a hyphen get an en dash."""
    pair = re.compile(r"\b([^\W\d_]+)-([^\W\d_]+)\b")
    return pair.sub(
        lambda m: f"{m[1]}–{m[2]}" if {m[1], m[2]} <= names else m[0], title
    )  # fmt: skip


def bibtex_title(title, names):
    """A title for BibTeX: proper names and acronyms (``JIT``, ``II``) braced, and two
    proper names joined by a hyphen joined by ``--``."""
    title = title_text(title, names).replace("–", "--")

    def protect(match):
        word = match.group()
        return f"{{{word}}}" if word in names or word.isupper() else word

    return WORD.sub(protect, title)


def ascii_key(text):
    """``Kułakowski`` → ``kulakowski`` (for labels and BibTeX keys)."""
    text = text.replace("ł", "l").replace("Ł", "L").replace("ø", "o").replace("Ø", "O")
    text = unicodedata.normalize("NFKD", text).encode("ascii", "ignore").decode()
    return re.sub(r"[^a-z0-9]", "", text.lower())


def key(ref):
    """``dieterich1979``; two entries of one first author and year get ``a``, ``b``, … in
    :func:`keys`."""
    first = ref["authors"][0]
    return ascii_key(first.get("family-names", first.get("name", ""))) + str(ref.get("year", ""))


def keys(refs):
    """A unique key per reference, in order."""
    base = [key(r) for r in refs]
    out = []
    for k, b in enumerate(base):
        if base.count(b) > 1:
            b += "abcdefghij"[base[:k].count(b)]
        out.append(b)
    return out


def initials(given):
    return " ".join(f"{part[0]}." for part in re.split(r"[\s.]+", given) if part)


def author_list(authors):
    """``Rice, J. R., & Ruina, A. L.`` (APA style)."""
    names = []
    for a in authors:
        if "family-names" in a:
            names.append(f"{a['family-names']}, {initials(a.get('given-names', ''))}".strip(", "))
        else:
            names.append(a["name"])
    if len(names) == 1:
        return names[0]
    return ", ".join(names[:-1]) + ", & " + names[-1]


def reference_text(ref, names=frozenset()):
    """One reference as a Markdown paragraph (APA-like)."""
    parts = [author_list(ref["authors"])]
    parts.append(f"({ref['year']})." if "year" in ref else "(n.d.).")
    title = title_text(ref["title"].rstrip("."), names)
    if ref.get("type") == "book":
        edition = f" ({ref['edition']} ed.)" if "edition" in ref else ""
        parts.append(f"*{title}*{edition}.")
        if "collection-title" in ref:
            parts.append(f"{ref['collection-title']} {ref.get('volume', '')}.".replace(" .", "."))
        if "publisher" in ref:
            parts.append(f"{ref['publisher']['name']}.")
    else:
        parts.append(f"{title}.")
        if "journal" in ref:
            where = f"*{ref['journal']}*"
            if "volume" in ref:
                where += f", {ref['volume']}"
                if "issue" in ref:
                    where += f"({ref['issue']})"
            if "start" in ref:
                where += f", {ref['start']}–{ref['end']}" if "end" in ref else f", {ref['start']}"
            parts.append(where + ".")
        else:
            affiliations = {a["affiliation"] for a in ref["authors"] if "affiliation" in a}
            parts += [f"{a}." for a in sorted(affiliations)]
    if "doi" in ref:
        parts.append(f"<https://doi.org/{ref['doi']}>")
    return " ".join(parts)


def bibtex_authors(authors):
    return " and ".join(
        f"{a['family-names']}, {a.get('given-names', '')}".strip(", ") if "family-names" in a
        else f"{{{a['name']}}}"
        for a in authors
    )  # fmt: skip


def bibtex(entry_type, key_, fields):
    lines = [f"@{entry_type}{{{key_},"]
    lines += [f"  {name:<9} = {{{value}}}," for name, value in fields if value not in (None, "")]
    return "\n".join(lines) + "\n}"


def reference_bibtex(ref, key_, names=frozenset()):
    pages = f"{ref['start']}--{ref['end']}" if "start" in ref and "end" in ref else None
    title = bibtex_title(ref["title"], names)
    if ref.get("type") == "book":
        return bibtex("book", key_, [
            ("author", bibtex_authors(ref["authors"])), ("title", title),
            ("edition", ref.get("edition")), ("series", ref.get("collection-title")),
            ("volume", ref.get("volume")), ("publisher", ref.get("publisher", {}).get("name")),
            ("year", ref.get("year")), ("doi", ref.get("doi")),
        ])  # fmt: skip
    kind = "article" if "journal" in ref else "unpublished"
    note = None if "journal" in ref else "AGH University of Science and Technology, Kraków"
    return bibtex(kind, key_, [
        ("author", bibtex_authors(ref["authors"])), ("title", title),
        ("journal", ref.get("journal")), ("year", ref.get("year")),
        ("volume", ref.get("volume")), ("number", ref.get("issue")), ("pages", pages),
        ("doi", ref.get("doi")), ("note", note),
    ])  # fmt: skip


class Citation(SphinxDirective):
    """How to cite the software: its entry and a BibTeX record."""

    def run(self):
        cff = read_cff()
        self.env.note_dependency(str(CFF))
        names = proper_names(cff)
        authors = author_list(cff["authors"])
        year = software_year(cff)
        title = title_text(cff["title"], names)
        text = [
            f"> {authors}. ({year or 'n.d.'}). *{title}* (version {cff['version']}) "
            f"[Computer software]. {cff['license']} licence.",
            "",
            "```bibtex",
            bibtex(
                "software",
                "rsf_sweep",
                [
                    ("author", bibtex_authors(cff["authors"])),
                    ("title", bibtex_title(cff["title"], names)),
                    ("year", year),
                    ("version", cff["version"]),
                    ("license", cff["license"]),
                ],
            ),  # fmt: skip
            "```",
        ]
        return self.parse_text_to_nodes("\n".join(text))


class References(SphinxDirective):
    """Every reference of CITATION.cff, labelled ``cite-<key>``, then all as BibTeX."""

    def run(self):
        cff = read_cff()
        refs = cff["references"]
        names = proper_names(cff)
        self.env.note_dependency(str(CFF))
        text = []
        for ref, key_ in zip(refs, keys(refs), strict=True):
            notes = title_text(" ".join(ref.get("notes", "").split()), names)
            entry = reference_text(ref, names) + (f" — *{notes}*" if notes else "")
            text += [f"(cite-{key_})=", "", entry, ""]
        records = [reference_bibtex(r, k, names) for r, k in zip(refs, keys(refs), strict=True)]
        text += ["All of them as BibTeX:", "", "```bibtex", "\n\n".join(records), "```"]
        return self.parse_text_to_nodes("\n".join(text))


def setup(app):
    app.add_directive("sweep-citation", Citation)
    app.add_directive("sweep-references", References)
    return {"parallel_read_safe": True, "parallel_write_safe": True}

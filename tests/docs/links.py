#!/usr/bin/python3
"""The documentation's links: README.md links every page of docs/, and every relative link of README.md and
docs/*.md names a file that exists and, after '#', a heading of that page (GitHub's anchors: the heading lower-cased,
backticks and punctuation other than '-' and '_' dropped, spaces as '-', a repeated heading numbered -1, -2, ...).
Prints one line per broken link and exits 1 when there is any. Usage: links.py SOURCE_DIR"""
import os
import re
import sys


def anchors(path):
    """The anchors GitHub gives the headings of the Markdown file at path (fenced code is not a heading)."""
    seen, out, fenced = {}, set(), False
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("```"):
                fenced = not fenced
            m = None if fenced else re.match(r"^#{1,6}\s+(.*?)\s*#*\s*$", line)
            if not m:
                continue
            slug = re.sub(r"[^\w\- ]", "", m.group(1).replace("`", "").strip().lower()).replace(" ", "-")
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            out.add(slug if n == 0 else f"{slug}-{n}")
    return out


def links(path):
    """(line number, target) of every inline Markdown link of the file at path outside fenced code."""
    fenced = False
    with open(path, encoding="utf-8") as fh:
        for number, line in enumerate(fh, 1):
            if line.startswith("```"):
                fenced = not fenced
                continue
            if fenced:
                continue
            for m in re.finditer(r"\]\(([^)\s]+)\)", line):
                yield number, m.group(1)


def main():
    if len(sys.argv) != 2:
        sys.exit("usage: links.py SOURCE_DIR")
    root = sys.argv[1]
    docs = sorted(os.path.join("docs", f) for f in os.listdir(os.path.join(root, "docs")) if f.endswith(".md"))
    pages = ["README.md"] + docs
    cache = {}
    problems = []
    readme_targets = set()
    for page in pages:
        for number, target in links(os.path.join(root, page)):
            if re.match(r"^[a-z][a-z0-9+.-]*:", target):  # https:, mailto: ...
                continue
            path, _, fragment = target.partition("#")
            resolved = os.path.normpath(os.path.join(os.path.dirname(page), path)) if path else page
            if page == "README.md":
                readme_targets.add(resolved)
            full = os.path.join(root, resolved)
            if path and not os.path.exists(full):
                problems.append(f"{page}:{number}: link to {target}: {resolved} does not exist")
                continue
            if fragment and resolved.endswith(".md"):
                if resolved not in cache:
                    cache[resolved] = anchors(full)
                if fragment not in cache[resolved]:
                    problems.append(f"{page}:{number}: link to {target}: {resolved} has no heading with anchor "
                                    f"'{fragment}'; link to one of its headings")
    for page in docs:
        if page not in readme_targets:
            problems.append(f"README.md: does not link {page}; every page of docs/ is linked from the README")
    for p in problems:
        print(p)
    sys.exit(1 if problems else 0)


if __name__ == "__main__":
    main()

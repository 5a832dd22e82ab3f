#!/usr/bin/python3
"""Every repository path the documentation names exists: relative Markdown links, and paths in
backticks whose first folder is one of the repository's own (src/, docs/, tests/, ...).
Usage: paths_test.py SOURCE_DIR; exit status 1 lists each missing path with file and line."""

import pathlib
import re
import sys

root = pathlib.Path(sys.argv[1]).resolve()
documents = [root / "README.md", root / "ros" / "README.md", root / "ros2" / "README.md",
             root / "python" / "README.md",
             root / "models" / "README.md", *sorted((root / "docs").glob("*.md"))]
top_level = {p.name for p in root.iterdir() if not p.name.startswith(".")}
# Paths that name what a build or a run creates, not files of the repository.
generated = ("build/", "build-", "demo_output/", "<prefix>", "/tmp/")

link = re.compile(r"\]\(([^)#\s]+)(?:#[^)]*)?\)")
code = re.compile(r"`([^`\s]+)`")
missing = []
for document in documents:
    for number, line in enumerate(document.read_text().splitlines(), 1):
        candidates = []
        for target in link.findall(line):
            if "://" not in target:
                candidates.append((document.parent / target).resolve())
        for token in code.findall(line):
            token = token.rstrip(".,:;")
            first = token.split("/")[0]
            if "/" in token and first in top_level and not token.startswith(generated):
                candidates.append(root / token.split(":")[0])
        for path in candidates:
            found = any(root.glob(str(path.relative_to(root)))) if "*" in str(path) else path.exists()
            if not found:
                missing.append(f"{document.relative_to(root)}:{number}: {path.relative_to(root)}")
for entry in missing:
    print("missing:", entry)
print(f"{len(documents)} documents checked, {len(missing)} missing paths")
sys.exit(1 if missing else 0)

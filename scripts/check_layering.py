#!/usr/bin/env python3
"""Checks the include layering of docs/design.md: a stage includes headers only from itself and the
stages below it. The order is read from the line `core <- detect <- ... <- cli` of docs/design.md, so
the document is the rule. src/python is an edge beside cli (nothing includes it).

Usage: check_layering.py [SOURCE_DIR]    exit 0 when clean, 1 with one line per wrong include
       check_layering.py --self-test      shows that a wrong include is caught (exit 0 when it is)
"""
import os
import re
import shutil
import sys
import tempfile

INCLUDE = re.compile(r'^\s*#\s*include\s+"([a-z_]+)/[^"]+"')
ORDER = re.compile(r"`(core(?:\s*<-\s*[a-z_]+)+)`")


def stage_order(source_dir):
    with open(os.path.join(source_dir, "docs", "design.md"), encoding="utf-8") as f:
        m = ORDER.search(f.read())
    if not m:
        sys.exit("docs/design.md: no layer line `core <- ... <- cli` found")
    stages = [s.strip() for s in m.group(1).split("<-")]
    rank = {s: i for i, s in enumerate(stages)}
    rank["python"] = rank[stages[-1]]  # the Python module is an edge like the CLI
    return rank


def violations(source_dir):
    rank = stage_order(source_dir)
    src = os.path.join(source_dir, "src")
    found = []
    for stage in sorted(os.listdir(src)):
        folder = os.path.join(src, stage)
        if not os.path.isdir(folder):
            continue
        if stage not in rank:
            found.append(f"src/{stage}: a folder that is not a layer of docs/design.md")
            continue
        for root, _, files in os.walk(folder):
            for name in sorted(files):
                if not name.endswith((".h", ".cc")):
                    continue
                path = os.path.join(root, name)
                with open(path, encoding="utf-8", errors="replace") as f:
                    for line_no, line in enumerate(f, 1):
                        m = INCLUDE.match(line)
                        if not m or m.group(1) not in rank:
                            continue
                        other = m.group(1)
                        edge_into_edge = other in ("cli", "python") and other != stage
                        if rank[other] > rank[stage] or edge_into_edge:
                            rel = os.path.relpath(path, source_dir)
                            found.append(f"{rel}:{line_no}: {stage} includes {other}/ (a layer above it)")
    return found


def self_test(source_dir):
    tmp = tempfile.mkdtemp(prefix="ssiu_layering_")
    try:
        os.makedirs(os.path.join(tmp, "docs"))
        shutil.copy(os.path.join(source_dir, "docs", "design.md"), os.path.join(tmp, "docs"))
        for stage, text in (("core", '#include "identify/index.h"\n'), ("identify", '#include "core/types.h"\n')):
            os.makedirs(os.path.join(tmp, "src", stage))
            with open(os.path.join(tmp, "src", stage, "x.h"), "w", encoding="utf-8") as f:
                f.write(text)
        found = violations(tmp)
    finally:
        shutil.rmtree(tmp)
    if len(found) == 1 and "src/core/x.h:1: core includes identify/" in found[0]:
        print("self-test: the wrong include core -> identify is caught, the right one is not")
        return 0
    print("self-test FAILED: expected exactly the core -> identify include, got", found)
    return 1


def main():
    args = sys.argv[1:]
    here = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    if args and args[0] == "--self-test":
        return self_test(args[1] if len(args) > 1 else here)
    source_dir = args[0] if args else here
    found = violations(source_dir)
    for v in found:
        print(v)
    if not found:
        print("layering: every include goes down the layers of docs/design.md")
    return 1 if found else 0


if __name__ == "__main__":
    sys.exit(main())

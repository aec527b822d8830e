#!/usr/bin/env python3
"""Checks every CMake target's direct links against the edge table in
docs/ARCHITECTURE.md, section 1 (ctest Boundary.edgesMatchTheTable).

The links come from CMake itself: `cmake --graphviz=DOT BUILD_DIR` (run by the
ctest fixture Boundary.cmakeGraph) gives every target's direct link items, ours
and third-party; the file API's codemodel in BUILD_DIR/.cmake/api/v1/reply
(queried by tests/boundary/CMakeLists.txt) says which targets are ours. The
table's rules are in docs/ARCHITECTURE.md under "The edge table".

Fails (exit 1) on a link a target's row does not allow, on a target of ours
without a row and on a row that names a target of a row below it; exit 2 when
the inputs cannot be read. The options --add-link, --disallow, --allow and
--drop-row change the graph or the table in memory: the negative controls use
them.

Usage: check_edges.py --table docs/ARCHITECTURE.md --dot graph.dot --build BUILD_DIR
"""
import argparse
import fnmatch
import glob
import json
import os
import re
import sys

TABLE_SECTION = "## 1."
TABLE_NAME = "docs/ARCHITECTURE.md (section 1, the edge table)"


class InputError(Exception):
    pass


def split_row(line):
    """The cells of a markdown table row, `|` inside backticks kept."""
    cells, cell, in_code = [], "", False
    for ch in line.strip().strip("|"):
        if ch == "`":
            in_code = not in_code
        if ch == "|" and not in_code:
            cells.append(cell.strip())
            cell = ""
        else:
            cell += ch
    cells.append(cell.strip())
    return cells


def strip_comments(cell):
    """A cell without parenthesised remarks."""
    prev = None
    while prev != cell:
        prev, cell = cell, re.sub(r"\([^()]*\)", "", cell)
    return cell


class Row:
    def __init__(self, names, folder, ours, third, line):
        self.names = names  # target names, possibly with '*'
        self.folder = folder  # as the table gives it, e.g. runtime/world/
        self.ours = ours  # items: full target names, 'its library', "its library's"
        self.third = third  # CMake target names, possibly "its library's"
        self.line = line


def parse_table(path):
    try:
        text = open(path, encoding="utf-8").read().splitlines()
    except OSError as e:
        raise InputError(f"cannot read {path}: {e}")
    start = next((i for i, l in enumerate(text) if l.startswith(TABLE_SECTION)), None)
    if start is None:
        raise InputError(f"{path} has no section starting '{TABLE_SECTION}'")
    header = None
    rows = []
    for i in range(start + 1, len(text)):
        line = text[i]
        if line.startswith("## "):
            break
        if not line.startswith("|"):
            if header is not None and rows:
                break
            continue
        cells = split_row(line)
        if header is None:
            header = [c.lower() for c in cells]
            try:
                col_t = header.index("target")
                col_o = next(k for k, c in enumerate(header) if c.startswith("may use"))
                col_3 = header.index("third-party")
                col_f = header.index("folder")
            except (ValueError, StopIteration):
                raise InputError(
                    f"{path}:{i + 1}: the table needs columns 'target', 'folder', 'may use (ours)' and 'third-party'")
            continue
        if set(line.replace("|", "").strip()) <= set("-: "):
            continue
        if len(cells) != len(header):
            raise InputError(f"{path}:{i + 1}: {len(cells)} cells where the header has {len(header)}")
        names = re.findall(r"`([^`]+)`", cells[col_t])
        if not names:
            raise InputError(f"{path}:{i + 1}: no target name in backticks in '{cells[col_t]}'")
        ours = []
        for item in strip_comments(cells[col_o]).split(","):
            item = item.strip().strip("`").strip()
            if not item or item in ("nothing", "—", "-"):
                continue
            ours.append(item)
        third_cell = cells[col_3]
        third = re.findall(r"`([^`]+)`", third_cell)
        if "its library's" in strip_comments(third_cell):
            third.append("its library's")
        folder = "".join(re.findall(r"`([^`]+)`", cells[col_f])).strip("/")
        rows.append(Row(names, folder, ours, third, i + 1))
    if header is None or not rows:
        raise InputError(f"{path}: no edge table found in section 1")
    return rows


def full_name(item):
    return item if item.startswith("sandtable") else "sandtable_" + item


def parse_dot(path):
    """{target: set(direct link items)} from cmake --graphviz output."""
    try:
        text = open(path, encoding="utf-8").read()
    except OSError as e:
        raise InputError(f"cannot read {path}: {e}")
    names = {}
    for node, label in re.findall(r'^\s*"(node\d+)"\s*\[\s*label\s*=\s*"((?:[^"\\]|\\.)*)"', text, re.M):
        # An alias shows as "REAL\n(ALIAS)": both names stand for the node.
        parts = label.split("\\n")
        names[node] = [parts[0]] + [p.strip("()") for p in parts[1:]]
    links = {}
    for a, b in re.findall(r'^\s*"(node\d+)"\s*->\s*"(node\d+)"', text, re.M):
        if a not in names or b not in names:
            raise InputError(f"{path}: an edge {a} -> {b} names a node without a label")
        links.setdefault(names[a][0], []).append(names[b])
    if not names:
        raise InputError(f"{path}: no nodes; is it cmake --graphviz output?")
    return links


def our_targets(build):
    """Names of the targets the project defines (not imported), from the codemodel."""
    reply = os.path.join(build, ".cmake", "api", "v1", "reply")
    indexes = sorted(glob.glob(os.path.join(reply, "index-*.json")))
    if not indexes:
        raise InputError(f"no CMake file API reply in {reply}: reconfigure the build tree")
    index = json.load(open(indexes[-1], encoding="utf-8"))
    try:
        model = json.load(open(os.path.join(reply, index["reply"]["codemodel-v2"]["jsonFile"]), encoding="utf-8"))
    except (KeyError, OSError) as e:
        raise InputError(f"the CMake file API reply in {reply} has no codemodel-v2: {e}")
    ours = {}
    for config in model["configurations"]:
        for t in config["targets"]:
            info = json.load(open(os.path.join(reply, t["jsonFile"]), encoding="utf-8"))
            if info["type"] != "UTILITY":
                ours[t["name"]] = info["paths"]["source"]
    return ours


def find_row(rows, target):
    """(row, what '*' matched) for a target: exact rows first, then wildcards."""
    for row in rows:
        if target in row.names:
            return row, None
    for row in rows:
        for pattern in row.names:
            if "*" in pattern and fnmatch.fnmatchcase(target, pattern):
                regex = "^" + re.escape(pattern).replace(r"\*", "(.*)") + "$"
                return row, re.match(regex, target).group(1)
    return None, None


def allowed_for(rows, target, seen=()):
    """(allowed ours, allowed third-party, problems) for a target's row."""
    row, star = find_row(rows, target)
    if row is None:
        return None, None, []
    ours, third, problems = set(), set(), []
    library = "sandtable_" + star if star is not None else None
    for item in row.ours + row.third:
        if item in ("its library", "its library's"):
            if library is None:
                problems.append(f"line {row.line}: '{item}' needs a wildcard row")
                continue
            if item == "its library":
                ours.add(library)
            elif library not in seen:
                lib_ours, lib_third, lib_problems = allowed_for(rows, library, seen + (target,))
                ours |= lib_ours or set()
                third |= lib_third or set()
                problems += lib_problems
    ours |= {full_name(i) for i in row.ours if not i.startswith("its library")}
    third |= {i for i in row.third if not i.startswith("its library")}
    return ours, third, problems


def check(rows, links, ours):
    errors = []
    # The table is in layer order: a row names only targets of rows above it.
    defined = {}
    for k, row in enumerate(rows):
        for item in row.ours:
            if item.startswith("its library"):
                continue
            name = full_name(item)
            if name not in defined:
                below = any(name in r.names for r in rows[k:])
                errors.append(
                    f"boundary: {TABLE_NAME} line {row.line}: `{row.names[0]}` may use '{item}', "
                    + ("whose row is not above it (rows go in layer order, so no arrow can point up)"
                       if below else "which is no target of the table (a typo?)"))
        for name in row.names:
            defined[name] = row
    for target in sorted(ours):
        row, _ = find_row(rows, target)
        if row is None:
            errors.append(
                f"boundary: target {target} (folder {ours[target]}/) has no row in {TABLE_NAME}; "
                f"add one in layer order: | `{target}` | `{ours[target]}/` | may use (ours) | third-party | holds |")
            continue
        # The folder CMake defines it in must be the row's folder or hold it
        # (runtime/CMakeLists.txt defines runtime/world's target).
        where = ours[target]
        if "*" not in "".join(row.names) and not (row.folder == where or row.folder.startswith(where + "/")):
            errors.append(f"boundary: {target} is defined in {where}/, but its row in {TABLE_NAME} "
                          f"(line {row.line}) gives the folder {row.folder}/")
        allowed_ours, allowed_third, problems = allowed_for(rows, target)
        errors += [f"boundary: {TABLE_NAME} {p}" for p in problems]
        for dep in links.get(target, []):
            name = dep[0]
            if name == target:
                continue  # CMake's own edge for a target's post-build step
            if name in ours:
                if name not in allowed_ours:
                    errors.append(
                        f"boundary: {target} links {name}, which its row in {TABLE_NAME} (line {row.line}) "
                        f"does not allow; it may use: {', '.join(sorted(allowed_ours)) or 'nothing'}")
            elif not any(n in allowed_third for n in dep):
                errors.append(
                    f"boundary: {target} links the third-party {' / '.join(dep)}, which its row in {TABLE_NAME} "
                    f"(line {row.line}) does not allow; it may link: {', '.join(sorted(allowed_third)) or 'none'}")
    return errors


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--table", required=True, help="docs/ARCHITECTURE.md")
    ap.add_argument("--dot", required=True, help="cmake --graphviz output")
    ap.add_argument("--build", required=True, help="the build tree (for the file API's codemodel)")
    ap.add_argument("--add-link", action="append", default=[], metavar="A=B",
                    help="negative control: pretend target A links B")
    ap.add_argument("--disallow", action="append", default=[], metavar="A=B",
                    help="negative control: remove B from the row of A")
    ap.add_argument("--drop-row", action="append", default=[], metavar="A",
                    help="negative control: remove the row of A")
    ap.add_argument("--allow", action="append", default=[], metavar="A=B",
                    help="negative control: add B (a short name) to the row of A")
    args = ap.parse_args()
    try:
        rows = parse_table(args.table)
        links = parse_dot(args.dot)
        ours = our_targets(args.build)
    except InputError as e:
        print(f"boundary: {e}")
        return 2
    for spec in args.add_link:
        a, b = spec.split("=", 1)
        links.setdefault(a, []).append([b])
    for spec in args.disallow:
        a, b = spec.split("=", 1)
        row, _ = find_row(rows, a)
        short = b[len("sandtable_"):] if b.startswith("sandtable_") else b
        row.ours = [i for i in row.ours if i not in (b, short)]
        row.third = [i for i in row.third if i != b]
    for spec in args.allow:
        a, b = spec.split("=", 1)
        find_row(rows, a)[0].ours.append(b)
    for name in args.drop_row:
        rows = [r for r in rows if name not in r.names]
    errors = check(rows, links, ours)
    for e in errors:
        print(e)
    n_links = sum(len(links.get(t, [])) for t in ours)
    if errors:
        print(f"boundary: FAILED: {len(errors)} problem(s) in {len(ours)} targets' {n_links} direct links "
              f"against {TABLE_NAME}")
        return 1
    print(f"boundary: {len(ours)} targets, {n_links} direct links, each allowed by its row in {TABLE_NAME}")
    return 0


if __name__ == "__main__":
    sys.exit(main())

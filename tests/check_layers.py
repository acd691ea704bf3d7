#!/usr/bin/env python3
"""Checks that the code keeps the layers of ARCHITECTURE.md (its "## Layers" table).

Usage: check_layers.py [SOURCE_DIR]   (default: the checkout this script is in)

The table has one row per module folder src/occmap/<module>/ and a "depends on" column; the
words of that column that name a module are its occmap dependencies, the rest (fmt, OpenCV,
Eigen, ...) are external libraries and ignored here. allowed(m) is m and the transitive closure
of its table dependencies. The checker fails, naming file and line, when

  1. the table and the folders disagree: a folder without a row, a row without a folder, a
     dependency on a row further down the table (the table promises "lower rows depend on
     higher rows"), an unknown module;
  2. the table and the build disagree: for each module the closure of the table's occmap
     dependencies must equal the closure of the occmap_<x> libraries in its
     occmap_module(NAME DEPS ...) call in src/occmap/CMakeLists.txt (redundant entries are
     fine on either side); the apps row likewise against what apps/CMakeLists.txt links into
     the occmap executable;
  3. a file under src/occmap/<m>/ (any depth, .h/.cc) includes occmap/<x>/... with x outside
     allowed(m). Test files (*_test.cc) get the same rule, widened by what occmap_module()
     links into occmap_<m>_test besides the module (read from the top-level CMakeLists.txt):
     today only occmap_testing, i.e. the one header occmap/util/testing.h. A test may thus
     not reach a module its test binary does not link. A module's TEST_DEPS
     (occmap_module(NAME DEPS ... TEST_DEPS ...)) widen its own tests' rule the same way.

Files under apps/ may include any module (they only must name an existing one).
Needs only python3 (no third-party modules). Exit 0 when clean, 1 with one line per problem.
"""

import os
import re
import sys

SOURCE_EXTENSIONS = (".h", ".hh", ".hpp", ".cc", ".cpp", ".inl")
INCLUDE_RE = re.compile(r'^\s*#\s*include\s*([<"])([^">]+)[">]')
TABLE_HEADER = ("module", "what it holds", "depends on")


class Problems:
    def __init__(self, root):
        self.root = root
        self.lines = []

    def add(self, path, line, message):
        rel = os.path.relpath(path, self.root)
        self.lines.append(f"{rel}:{line}: {message}" if line else f"{rel}: {message}")


def read_lines(path):
    with open(path, encoding="utf-8") as f:
        return f.read().split("\n")


def split_row(line):
    # Cells of a Markdown table row; "\|" inside a cell is not a separator.
    cells = re.split(r"(?<!\\)\|", line.strip())
    return [c.strip() for c in cells[1:-1]]


def strip_ticks(text):
    return text.replace("`", "").strip()


def parse_layer_table(path, problems):
    """Rows of the "## Layers" table: list of (line_no, module, [dependency words])."""
    lines = read_lines(path)
    rows = []
    in_section = False
    header_seen = False
    for number, line in enumerate(lines, start=1):
        if line.startswith("## "):
            if in_section:
                break
            in_section = line.strip() == "## Layers"
            continue
        if not in_section or not line.lstrip().startswith("|"):
            if in_section and header_seen and rows and line.strip():
                break  # the table ended
            continue
        cells = split_row(line)
        if not header_seen:
            if tuple(c.lower() for c in cells) != TABLE_HEADER:
                problems.add(path, number, "the Layers table must have the columns "
                             f"{' | '.join(TABLE_HEADER)}; found {' | '.join(cells)}")
                return []
            header_seen = True
            continue
        if all(re.fullmatch(r":?-+:?", c) for c in cells):
            continue  # the separator row
        if len(cells) != 3:
            problems.add(path, number, f"expected 3 cells in the Layers table, found {len(cells)}")
            continue
        module = strip_ticks(cells[0])
        words = []
        for item in cells[2].split(","):
            item = re.sub(r"\([^)]*\)", "", strip_ticks(item)).strip()
            if item:
                words.append(item.split()[0])
        rows.append((number, module, words))
    if not header_seen:
        problems.add(path, 0, "no '## Layers' table (module | what it holds | depends on) found")
    return rows


def strip_cmake_comments(text):
    return "\n".join(re.sub(r"#.*", "", line) for line in text.split("\n"))


def parse_cmake_modules(path):
    """occmap_module(NAME DEPS ... TEST_DEPS ...) calls: {name: (line_no, [dep tokens],
    [test dep tokens])}; TEST_DEPS are linked into the module's tests only."""
    with open(path, encoding="utf-8") as f:
        text = strip_cmake_comments(f.read())
    modules = {}
    for match in re.finditer(r"\boccmap_module\s*\(([^)]*)\)", text):
        tokens = match.group(1).split()
        if not tokens:
            continue
        deps = []
        test_deps = []
        keyword = None
        for token in tokens[1:]:
            if token in ("DEPS", "EXCLUDE", "TEST_DEPS"):
                keyword = token
            elif keyword == "DEPS":
                deps.append(token)
            elif keyword == "TEST_DEPS":
                test_deps.append(token)
        line = text.count("\n", 0, match.start()) + 1
        modules[tokens[0]] = (line, deps, test_deps)
    return modules


def parse_test_links(path):
    """The occmap_* libraries occmap_module() links into occmap_<name>_test, or None."""
    with open(path, encoding="utf-8") as f:
        text = strip_cmake_comments(f.read())
    match = re.search(r"target_link_libraries\s*\(\s*occmap_\$\{name\}_test\b([^)]*)\)", text)
    if not match:
        return None
    return [t for t in match.group(1).split() if t.startswith("occmap_")]


def parse_app_links(path):
    """(line, occmap_* libraries linked into the occmap executable) or None."""
    with open(path, encoding="utf-8") as f:
        text = strip_cmake_comments(f.read())
    match = re.search(r"target_link_libraries\s*\(\s*occmap\s([^)]*)\)", text)
    if not match:
        return None
    line = text.count("\n", 0, match.start()) + 1
    return line, [t for t in match.group(1).split() if t.startswith("occmap_")]


def closure(module, deps_of):
    seen = set()
    stack = list(deps_of.get(module, ()))
    while stack:
        m = stack.pop()
        if m in seen:
            continue
        seen.add(m)
        stack.extend(deps_of.get(m, ()))
    return seen


def source_files(top):
    for directory, _, names in os.walk(top):
        for name in sorted(names):
            if name.endswith(SOURCE_EXTENSIONS):
                yield os.path.join(directory, name)


def included_module(path, delimiter, target, src_dir):
    """The occmap module an include names, None if it names none, "" for occmap/ not a module."""
    if delimiter == '"' and not target.startswith("occmap/"):
        # A quoted include resolves beside the file first ("../fusion/x.h" would dodge the rule).
        resolved = os.path.normpath(os.path.join(os.path.dirname(path), target))
        occmap_dir = os.path.join(src_dir, "occmap")
        if os.path.exists(resolved) and resolved.startswith(occmap_dir + os.sep):
            target = os.path.relpath(resolved, src_dir).replace(os.sep, "/")
    match = re.match(r"occmap/([^/]+)/", target)
    return match.group(1) if match else None


def fmt_set(modules):
    return ", ".join(sorted(modules)) if modules else "(none)"


def main(argv):
    root = os.path.abspath(argv[1] if len(argv) > 1 else
                           os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    problems = Problems(root)
    arch = os.path.join(root, "ARCHITECTURE.md")
    src_dir = os.path.join(root, "src")
    occmap_dir = os.path.join(src_dir, "occmap")
    modules_cmake = os.path.join(occmap_dir, "CMakeLists.txt")
    top_cmake = os.path.join(root, "CMakeLists.txt")
    apps_dir = os.path.join(root, "apps")
    apps_cmake = os.path.join(apps_dir, "CMakeLists.txt")

    folders = sorted(d for d in os.listdir(occmap_dir)
                     if os.path.isdir(os.path.join(occmap_dir, d)))

    # 1. The table against the folders, and its own order.
    rows = parse_layer_table(arch, problems)
    table = {}        # module -> (line, [occmap deps])
    app_row = None    # (line, [occmap deps])
    row_names = [m for _, m, _ in rows]
    for number, module, words in rows:
        deps = [w for w in words if w in folders or w in row_names]
        if module.startswith("apps"):
            app_row = (number, deps)
            continue
        if module in table:
            problems.add(arch, number, f"module '{module}' has two rows in the Layers table")
        table[module] = (number, deps)
        if module not in folders:
            problems.add(arch, number, f"the Layers table has a row '{module}' but there is no "
                         f"folder src/occmap/{module}/")
    order = [m for _, m, _ in rows]
    for number, module, words in rows:
        for dep in (w for w in words if w in folders or w in row_names):
            if dep in order and order.index(dep) >= order.index(module):
                problems.add(arch, number, f"'{module}' depends on '{dep}', which is not above it "
                             "in the Layers table (lower rows depend on higher rows)")
    for folder in folders:
        if folder not in table:
            problems.add(arch, 0, f"src/occmap/{folder}/ has no row in the Layers table")

    table_deps = {m: deps for m, (_, deps) in table.items()}

    # 2. The table against CMake.
    cmake = parse_cmake_modules(modules_cmake)
    cmake_deps = {}
    for module, (line, tokens, _) in cmake.items():
        cmake_deps[module] = [t[len("occmap_"):] for t in tokens
                              if t.startswith("occmap_") and t[len("occmap_"):] in folders]
        if module not in folders:
            problems.add(modules_cmake, line, f"occmap_module({module}) has no folder "
                         f"src/occmap/{module}/")
    for folder in folders:
        if folder not in cmake:
            problems.add(modules_cmake, 0, f"src/occmap/{folder}/ has no occmap_module({folder} ...)")
    for module in folders:
        if module not in table or module not in cmake:
            continue
        from_table = closure(module, table_deps)
        from_cmake = closure(module, cmake_deps)
        if from_table != from_cmake:
            number = table[module][0]
            line = cmake[module][0]
            detail = []
            if from_cmake - from_table:
                detail.append(f"CMake only: {fmt_set(from_cmake - from_table)}")
            if from_table - from_cmake:
                detail.append(f"table only: {fmt_set(from_table - from_cmake)}")
            problems.add(arch, number, f"the Layers table's dependencies of '{module}' "
                         f"({fmt_set(table_deps[module])}, closure {fmt_set(from_table)}) differ "
                         f"from src/occmap/CMakeLists.txt:{line} occmap_module({module} DEPS "
                         f"...) (closure {fmt_set(from_cmake)}): {'; '.join(detail)}")
    app_links = parse_app_links(apps_cmake) if os.path.exists(apps_cmake) else None
    if app_row is not None and app_links is not None:
        line, tokens = app_links
        linked = [t[len("occmap_"):] for t in tokens if t[len("occmap_"):] in folders]
        cmake_deps["<apps>"] = linked
        table_deps["<apps>"] = app_row[1]
        from_table = closure("<apps>", table_deps)
        from_cmake = closure("<apps>", cmake_deps)
        if from_table != from_cmake:
            problems.add(arch, app_row[0], f"the Layers table's apps row ({fmt_set(app_row[1])}) "
                         f"differs from apps/CMakeLists.txt:{line} (links {fmt_set(linked)}): "
                         f"closures {fmt_set(from_table)} vs {fmt_set(from_cmake)}")

    # What a test binary links besides its module: only files of those targets are reachable.
    test_links = parse_test_links(top_cmake)
    test_extra_modules = set()
    test_extra_headers = set()
    if test_links is None:
        problems.add(top_cmake, 0, "cannot find occmap_module()'s target_link_libraries("
                     "occmap_${name}_test ...); update tests/check_layers.py")
    else:
        for token in test_links:
            name = token[len("occmap_"):]
            if name in ("${name}", "warnings"):
                continue  # the module itself; occmap_warnings only adds compiler flags
            if name == "testing":
                # occmap_testing is util/testing.cc alone (src/occmap/CMakeLists.txt).
                test_extra_headers.add("occmap/util/testing.h")
            elif name in folders:
                test_extra_modules |= {name} | closure(name, table_deps)
            else:
                problems.add(top_cmake, 0, f"occmap_module() links {token} into the tests; "
                             "tests/check_layers.py does not know what it allows")

    # 3. Every include of every module file.
    for module in folders:
        if module not in table:
            continue  # reported above; its includes cannot be judged without a row
        allowed = {module} | closure(module, table_deps)
        # The module's own TEST_DEPS (occmap_module(... TEST_DEPS ...)): its tests only.
        own_test_modules = set()
        for token in cmake.get(module, (0, [], []))[2]:
            name = token[len("occmap_"):] if token.startswith("occmap_") else None
            if name in folders:
                if name == module or module in closure(name, table_deps):
                    problems.add(modules_cmake, cmake[module][0], f"occmap_module({module}) lists "
                                 f"{token} in TEST_DEPS, which depends on '{module}' itself")
                own_test_modules |= {name} | closure(name, table_deps)
        for path in source_files(os.path.join(occmap_dir, module)):
            is_test = path.endswith("_test.cc")
            allowed_here = allowed | test_extra_modules | own_test_modules if is_test else allowed
            for number, line in enumerate(read_lines(path), start=1):
                match = INCLUDE_RE.match(line)
                if not match:
                    continue
                target = match.group(2)
                included = included_module(path, match.group(1), target, src_dir)
                if included is None:
                    continue
                if included not in folders:
                    problems.add(path, number, f'#include "{target}": there is no module '
                                 f"src/occmap/{included}/")
                elif included not in allowed_here and not (is_test and target in test_extra_headers):
                    kind = "test of " if is_test else ""
                    extra = (" (tests also: " + ", ".join(sorted(test_extra_headers)) + ")"
                             if is_test and test_extra_headers else "")
                    problems.add(path, number, f'#include "{target}": {kind}module \'{module}\' '
                                 f"may include only {fmt_set(allowed_here)}{extra}; '{included}' "
                                 "is not in its closure in ARCHITECTURE.md's Layers table")
    if os.path.isdir(apps_dir):
        for path in source_files(apps_dir):
            for number, line in enumerate(read_lines(path), start=1):
                match = INCLUDE_RE.match(line)
                if match:
                    included = included_module(path, match.group(1), match.group(2), src_dir)
                    if included is not None and included not in folders:
                        problems.add(path, number, f'#include "{match.group(2)}": there is no '
                                     f"module src/occmap/{included}/")

    if problems.lines:
        print("check_layers: the code does not keep ARCHITECTURE.md's Layers table:")
        for line in problems.lines:
            print("  " + line)
        print(f"{len(problems.lines)} problem(s). Fix the include, or, when the dependency is "
              "meant, add it to the module's occmap_module(... DEPS) and its table row.")
        return 1
    print(f"check_layers: {len(folders)} modules, table, CMake and includes agree")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))

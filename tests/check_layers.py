#!/usr/bin/env python3
"""Check that no layer includes a header of a layer above it.

Layers: core <- mesh <- {fluid, solid} <- coupling <- io <- scene <- run <- {render, bench}
<- cli (the application's rooms above coupling); fluid and solid never include each other,
nor do render and bench, and no layer includes tests/. Inside fluid/, the two discretisations
fluid/tet/ and fluid/grid/ never include each other, and what they share (fluid/ itself)
includes neither. Every quoted #include in these folders is resolved — `"<layer>/x.hpp"` by
its first folder, any other
quoted include relative to the including file — and must land in the file's own layer or one
below.

Usage: check_layers.py SOURCE_DIR   (exit 1 and one line per violation)
       check_layers.py --self-test
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import cxx_scan  # noqa: E402

# What each layer may include (itself and everything below it).
ALLOWED = {
    "core": {"core"},
    "mesh": {"core", "mesh"},
    "fluid": {"core", "mesh", "fluid"},
    "solid": {"core", "mesh", "solid"},
    "coupling": {"core", "mesh", "fluid", "solid", "coupling"},
}
# The application's rooms, each above the one before it; render and bench are siblings.
_BASE = ALLOWED["coupling"]
ALLOWED["io"] = _BASE | {"io"}
ALLOWED["scene"] = ALLOWED["io"] | {"scene"}
ALLOWED["run"] = ALLOWED["scene"] | {"run"}
ALLOWED["render"] = ALLOWED["io"] | {"render"}
ALLOWED["bench"] = ALLOWED["run"] | {"bench"}
ALLOWED["cli"] = ALLOWED["run"] | {"render", "bench", "cli"}
ORDER = "core <- mesh <- {fluid, solid} <- coupling <- io <- scene <- run <- {render, bench} <- cli"
TOP_LEVEL = set(ALLOWED) | {"tests"}


def target_layer(root, including, target):
    """The top-level folder a quoted include resolves to, or None (outside the tree's
    folders, e.g. a third-party header)."""
    first = target.split("/")[0]
    if first in TOP_LEVEL:
        return first
    here = os.path.normpath(os.path.join(os.path.dirname(including), target))
    rel = os.path.relpath(here, root)
    top = rel.split(os.sep)[0]
    return top if top in TOP_LEVEL and os.path.exists(here) else None


# Inside fluid/: what each part may include of fluid/ ("" is fluid/ itself, what both share).
FLUID_PARTS = {"": {""}, "tet": {"", "tet"}, "grid": {"", "grid"}}


def fluid_part(rel):
    """The part of fluid/ a path inside it belongs to: "tet", "grid" or "" (shared)."""
    parts = rel.replace(os.sep, "/").split("/")
    return parts[1] if len(parts) > 2 and parts[1] in FLUID_PARTS else ""


def fluid_target(root, including, target):
    """The path (relative to root) of a quoted include that lands in fluid/."""
    if target.split("/")[0] == "fluid":
        return target
    return os.path.relpath(os.path.normpath(os.path.join(os.path.dirname(including), target)),
                           root)


def check(root):
    errors = []
    for layer in ALLOWED:
        for dirpath, dirnames, filenames in os.walk(os.path.join(root, layer)):
            dirnames.sort()
            for f in sorted(filenames):
                if not f.endswith((".cpp", ".hpp", ".h")):
                    continue
                full = os.path.join(dirpath, f)
                rel = os.path.relpath(full, root)
                for line, quoted, target in cxx_scan.read(full).includes:
                    if not quoted:
                        continue
                    to = target_layer(root, full, target)
                    if to is not None and to not in ALLOWED[layer]:
                        errors.append(f"{rel}:{line}: #include \"{target}\": {layer}/ may "
                                      f"include only {', '.join(sorted(ALLOWED[layer]))} "
                                      f"({ORDER})")
                    elif layer == "fluid" and to == "fluid":
                        mine = fluid_part(rel)
                        theirs = fluid_part(fluid_target(root, full, target))
                        if theirs not in FLUID_PARTS[mine]:
                            errors.append(f"{rel}:{line}: #include \"{target}\": "
                                          f"fluid/{mine + '/' if mine else ''} may not include "
                                          f"fluid/{theirs}/ (fluid/tet and fluid/grid never "
                                          f"include each other; fluid/ includes neither)")
    return errors


def self_test():
    cases = [
        ("clean", {"mesh/a.hpp": '#include "core/types.hpp"\n#include <vector>\n',
                   "run/b.cpp": '#include "coupling/x.hpp"\n#include "b.hpp"\n'}, []),
        ("io includes scene", {"io/a.cpp": '#include "scene/scene.hpp"\n'},
         ['io/a.cpp:1: #include "scene/scene.hpp": io/ may include only']),
        ("rooms that are siblings", {"render/a.cpp": '#include "bench/b.hpp"\n',
                                     "bench/b.cpp": '#include "render/a.hpp"\n'},
         ['render/a.cpp:1: #include "bench/b.hpp": render/ may include only',
          'bench/b.cpp:1: #include "render/a.hpp": bench/ may include only']),
        ("scene includes render", {"scene/a.hpp": '#include "render/render.hpp"\n'},
         ['scene/a.hpp:1: #include "render/render.hpp": scene/ may include only']),
        ("lower includes higher", {"core/a.cpp": '// x\n#include "mesh/tet_mesh.hpp"\n'},
         ['core/a.cpp:2: #include "mesh/tet_mesh.hpp": core/ may include only core']),
        ("siblings", {"fluid/a.hpp": '#include "solid/world.hpp"\n'},
         ['fluid/a.hpp:1: #include "solid/world.hpp": fluid/ may include only core, fluid, mesh']),
        ("relative path", {"solid/a.cpp": '#include "../coupling/c.hpp"\n',
                           "coupling/c.hpp": ""},
         ['solid/a.cpp:1: #include "../coupling/c.hpp": solid/ may include only']),
        ("tests", {"coupling/a.cpp": '#include "tests/test_util.hpp"\n'},
         ['coupling/a.cpp:1: #include "tests/test_util.hpp": coupling/ may include only']),
        ("commented out", {"core/a.cpp": '/*\n#include "cli/x.hpp"\n*/\n'}, []),
        ("fluid parts", {"fluid/tet/a.cpp": '#include "fluid/params.hpp"\n#include "b.hpp"\n',
                         "fluid/tet/b.hpp": "",
                         "fluid/grid/c.cpp": '#include "fluid/grid/d.hpp"\n#include "../e.hpp"\n',
                         "fluid/e.hpp": ""}, []),
        ("tet includes grid", {"fluid/tet/a.cpp": '#include "fluid/grid/grid.hpp"\n'},
         ['fluid/tet/a.cpp:1: #include "fluid/grid/grid.hpp": fluid/tet/ may not include '
          'fluid/grid/']),
        ("grid includes tet", {"fluid/grid/a.hpp": '#include "../tet/b.hpp"\n',
                               "fluid/tet/b.hpp": ""},
         ['fluid/grid/a.hpp:1: #include "../tet/b.hpp": fluid/grid/ may not include fluid/tet/']),
        ("shared includes tet", {"fluid/a.hpp": '#include "fluid/tet/mesh.hpp"\n'},
         ['fluid/a.hpp:1: #include "fluid/tet/mesh.hpp": fluid/ may not include fluid/tet/']),
    ]
    return cxx_scan.self_test_trees(cases, check)


def main(argv):
    return cxx_scan.check_main(argv, "check_layers.py", check, self_test,
                               "layers: no layer includes a header of a layer above it; "
                               "fluid/tet and fluid/grid include only their own and what they "
                               "share",
                               "{n} include(s) against the layering")


if __name__ == "__main__":
    sys.exit(main(sys.argv))

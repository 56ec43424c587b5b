"""The repository's folder, when Python runs in the folder above a clone named ``fpr`` and imports ``fpr``.

Python looks for ``fpr`` in the current folder first: there it finds this clone, whose folder has the
package's name. Without this file the clone would be taken for an empty namespace package ``fpr`` (no
``fpr.load``, whatever fpr is installed). With it, ``import fpr`` loads the clone's own package
(``fpr/__init__.py`` inside this folder) and puts the clone first on ``sys.path``, so that ``planners`` and
``controllers`` come from the same clone: the folder above a clone behaves as the clone itself does.
Nothing here runs when fpr is imported from an installation or from inside the clone.
"""

import importlib.util as _util
import sys as _sys
from pathlib import Path as _Path

_clone = _Path(__file__).resolve().parent
_package = _clone / "fpr"
if __name__ == "fpr" and (_package / "__init__.py").is_file():
    if str(_clone) not in _sys.path:
        _sys.path.insert(0, str(_clone))
    _spec = _util.spec_from_file_location("fpr", _package / "__init__.py",
                                          submodule_search_locations=[str(_package)])
    _module = _util.module_from_spec(_spec)
    _sys.modules["fpr"] = _module  # the import statement returns what sys.modules holds when this file ends
    _spec.loader.exec_module(_module)

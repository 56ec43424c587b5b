"""Build of fpr's native parts, all in ``fpr/_native/`` (everything else is in pyproject.toml).

* ``fpr._native._pinocchio`` (C++, ``fpr/_native/cpp/``): the plant's steps, its kinematic points and the
  minimal model's terms by Pinocchio's own algorithms, linked against the ``libpinocchio_default`` library of
  the ``libpinocchio`` wheel (its headers and Boost's from the same wheels, Eigen's from ``cmeel-eigen``: the
  ``[build-system] requires`` of pyproject.toml);
  and the closed loop's plain ticks (``cpp/loop.cpp``, which calls the C parts' kernels through their capsules,
  ``kernels.h``);
* ``fpr._native._alloc``, ``_attitude``, ``_watch``, ``_jets`` (C): the allocation tick and the inner loop's
  float part, the attitude model's numpy part, the watch's screen, the jet products.

Every source is compiled with warnings as errors, all of them in parallel (one job per core;
``FPR_NATIVE_JOBS`` sets another number). A part that does not build fails the install with the compiler's
messages and a line saying how to get the pure-Python install instead: ``FPR_NATIVE=0 pip install -e .``
builds no native part (the same variable at run time chooses the Python paths, :mod:`fpr._native`).
``FPR_NATIVE_SANITIZE=1`` builds the parts with AddressSanitizer and UndefinedBehaviorSanitizer (CI's
sanitizer job). ``-ffp-contract=off``: no fused multiply-adds, so that the C parts round as their Python
references do, operation by operation.
"""

import os
import sys
import sysconfig
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

PURE = os.environ.get("FPR_NATIVE", "").strip().lower() in ("0", "off", "false", "no")
SANITIZE = os.environ.get("FPR_NATIVE_SANITIZE", "").strip().lower() in ("1", "on", "true", "yes")
NATIVE = Path("fpr/_native")

WARNINGS = ["-Wall", "-Wextra", "-Werror"]
SANITIZERS = ["-fsanitize=address,undefined", "-fno-sanitize-recover=undefined", "-fno-omit-frame-pointer"]
# -g0: Python's own flags (sysconfig's CFLAGS) may ask for debug information, which for the C++ part makes the
# build slower and the library a hundred times larger
OPTIMISE = ["-O1", "-g"] + SANITIZERS if SANITIZE else ["-O2", "-g0"]
# Pinocchio's own compile definitions (its CMake target pinocchio_headers / pinocchio_default): the Boost MPL
# limits its joint variant needs, and the declarations of the algorithms the library instantiates (extern
# template), which spare this build their instantiation. PINOCCHIO_DISABLE_UNSUPPORTED_WARNINGS: the
# constraint dynamics' API is marked "will change" by a deprecation attribute, which -Werror would turn into
# an error.
PINOCCHIO_MACROS = [("BOOST_MPL_LIMIT_LIST_SIZE", "30"), ("BOOST_MPL_LIMIT_VECTOR_SIZE", "30"),
                    ("BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", None), ("BOOST_FUSION_INVOKE_MAX_ARITY", "12"),
                    ("PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION", None),
                    ("PINOCCHIO_DISABLE_UNSUPPORTED_WARNINGS", None)]
HINT = ("fpr: a native part did not build (the compiler's messages are above). Fix the build, or install the "
        "pure-Python version, slower in the closed loop: FPR_NATIVE=0 pip install -e .")


def cmeel_prefix() -> Path:
    """The folder of the cmeel wheels (``<site-packages>/cmeel.prefix``) that holds Pinocchio's, Boost's and
    Eigen's headers and Pinocchio's library: in pip's build environment, the ``[build-system] requires``.
    """
    for entry in sys.path:
        prefix = Path(entry or ".") / "cmeel.prefix"
        if (prefix / "include" / "pinocchio" / "config.hpp").is_file():
            if not (prefix / "include" / "eigen3" / "Eigen" / "Core").is_file():
                raise SystemExit(f"fpr: Eigen's headers are missing from {prefix} (pip install cmeel-eigen). {HINT}")
            return prefix
    raise SystemExit("fpr: Pinocchio's headers were not found (the libpinocchio wheel's cmeel.prefix on sys.path; "
                     f"pip install libpinocchio). {HINT}")


def numpy_include() -> str:
    """numpy's C headers' folder (numpy imported only when a part is built)."""
    import numpy

    return numpy.get_include()


def extensions() -> list[Extension]:
    """The native parts (none for the pure-Python install)."""
    if PURE:
        return []
    system = [f"-isystem{numpy_include()}"]  # others' headers: their warnings are not ours
    c_args = OPTIMISE + WARNINGS + ["-std=c11", "-ffp-contract=off"] + system
    parts = [Extension(f"fpr._native._{name}", [str(NATIVE / f"{name}.c")],
                       depends=[str(NATIVE / "dense.h"), str(NATIVE / "kernels.h")],
                       extra_compile_args=c_args, extra_link_args=SANITIZERS if SANITIZE else [])
             for name in ("alloc", "attitude", "watch", "jets")]
    prefix = cmeel_prefix()
    include = prefix / "include"
    version = sysconfig.get_config_var("py_version_nodot")
    cpp = NATIVE / "cpp"
    sources = [str(cpp / f"{name}.cpp") for name in ("module", "bridge", "plant", "minimal", "measure",
                                                            "measure_module", "loop", "outer")]
    parts.append(Extension(
        "fpr._native._pinocchio", sources,
        depends=[str(cpp / name) for name in ("native.hpp", "arrays.hpp")] + [str(NATIVE / "kernels.h")],
        language="c++", define_macros=PINOCCHIO_MACROS,
        extra_compile_args=OPTIMISE + WARNINGS + ["-std=c++17", "-ffp-contract=off", f"-isystem{include}",
                                                  f"-isystem{include / 'eigen3'}"] + system,
        library_dirs=[str(prefix / "lib")], libraries=["pinocchio_default", f"boost_python{version}"],
        extra_link_args=SANITIZERS if SANITIZE else []))
    return parts


class BuildNative(build_ext):
    """build_ext with every source of every part compiled at once on a pool of threads, and a failure that
    says what to do.
    """

    def build_extensions(self):
        """Compile every source of every part on a pool of threads, then link each part."""
        self.check_extensions_list(self.extensions)
        jobs = int(os.environ.get("FPR_NATIVE_JOBS", "0") or 0) or os.cpu_count() or 1
        compile_one = self.compiler.compile
        work = [(ext, source) for ext in self.extensions for source in ext.sources]
        for _, source in work:  # the objects' folders made first: the threads would race to make them
            for obj in self.compiler.object_filenames([source], output_dir=self.build_temp):
                os.makedirs(os.path.dirname(obj) or ".", exist_ok=True)

        def compile_source(item):
            ext, source = item
            macros = ext.define_macros[:] + [(undef,) for undef in ext.undef_macros]
            return source, compile_one([source], output_dir=self.build_temp, macros=macros,
                                       include_dirs=ext.include_dirs, debug=self.debug,
                                       extra_postargs=ext.extra_compile_args, depends=ext.depends)

        try:
            with ThreadPoolExecutor(max_workers=jobs) as pool:
                objects = dict(pool.map(compile_source, work))
            self.compiler.compile = lambda sources, *args, **kwargs: [o for s in sources for o in objects[s]]
            super().build_extensions()
        except Exception as error:
            raise SystemExit(f"{error}\n{HINT}") from error
        finally:
            self.compiler.compile = compile_one


setup(ext_modules=extensions(), cmdclass={"build_ext": BuildNative})

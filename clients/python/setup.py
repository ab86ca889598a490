# SPDX-License-Identifier: MIT
"""setup.py - puts the in-process library into the `mcf` package.

pyproject.toml says everything else. `pip install ./clients/python` builds in
place (pip >= 21.3), so the repository is two levels up: its
build/libmcfpy.so (MCF_BUILD names another build directory; MCF_LIBRARY a
file, which is never built) is copied into the package as mcf/_libmcfpy.so,
built first with `make pylib` when it is missing. Without a repository or a library the
package installs without it: mcfd_client works, `import mcf` says what to
build.
"""
import os
import shutil
import subprocess

from setuptools import setup
from setuptools.command.build_py import build_py

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
ROOT = os.path.dirname(ROOT) if os.path.basename(ROOT) == "clients" else ROOT


class BuildWithLibrary(build_py):
    def run(self):
        super().run()
        named = os.environ.get("MCF_LIBRARY")   # named: used as it is, never built
        lib = named or os.path.join(ROOT, os.environ.get("MCF_BUILD", "build"), "libmcfpy.so")
        if not named and not os.path.exists(lib) and \
                os.path.exists(os.path.join(ROOT, "Makefile")):
            subprocess.run(["make", "-C", ROOT, "pylib"], check=False)
        if os.path.exists(lib):
            shutil.copyfile(lib, os.path.join(self.build_lib, "mcf", "_libmcfpy.so"))
        else:
            print("setup.py: no %s: mcf (in-process) will not import; mcfd_client will" % lib)


setup(cmdclass={"build_py": BuildWithLibrary})

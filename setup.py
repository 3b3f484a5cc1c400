"""setuptools glue for pyproject.toml: the extension specula._specula is built by the project's CMake (target
specula_python, nothing else) for the interpreter running this script, then copied where setuptools packs it.

Environment: SPECULA_BUILD_DIR reuses an existing CMake build tree (scripts/test passes build/, whose module is
already built, so making the wheel costs seconds); SPECULA_CMAKE_ARGS adds configure arguments (e.g.
-DSPECULA_NATIVE=OFF for a wheel that runs on other x86-64 CPUs)."""
import os
import re
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

from setuptools import Extension, setup
from setuptools.command.build_ext import build_ext

ROOT = Path(__file__).resolve().parent


def version():
    m = re.search(r"project\(specula VERSION ([0-9.]+)", (ROOT / "CMakeLists.txt").read_text())
    return m.group(1)


class CMakeBuild(build_ext):
    def build_extension(self, ext):
        build = Path(os.environ.get("SPECULA_BUILD_DIR") or Path(self.build_temp).resolve() / "cmake")
        if not (build / "CMakeCache.txt").exists() or not os.environ.get("SPECULA_BUILD_DIR"):
            args = ["-DCMAKE_BUILD_TYPE=Release", f"-DPython3_EXECUTABLE={sys.executable}",
                    "-DSPECULA_TESTS=OFF", "-DSPECULA_BENCH=OFF", "-DSPECULA_PYTHON=ON"]
            try:  # pybind11 from the index (isolated builds) when Debian's pybind11-dev is absent
                import pybind11
                args.append(f"-Dpybind11_DIR={pybind11.get_cmake_dir()}")
            except ImportError:
                pass
            if shutil.which("ninja"):
                args += ["-G", "Ninja"]
            args += shlex.split(os.environ.get("SPECULA_CMAKE_ARGS", ""))
            subprocess.run(["cmake", "-S", str(ROOT), "-B", str(build), *args], check=True)
        jobs = os.environ.get("CMAKE_BUILD_PARALLEL_LEVEL") or str(os.cpu_count() or 1)
        subprocess.run(["cmake", "--build", str(build), "--target", "specula_python", "-j", jobs], check=True)
        built = sorted((build / "python" / "specula").glob("_specula*.so"))
        if not built:
            raise RuntimeError(f"{build}/python/specula: no _specula module after the build (is the Python "
                               "module disabled, or were python3-dev, numpy or pybind11 not found?)")
        target = Path(self.get_ext_fullpath(ext.name))
        target.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(built[-1], target)


setup(version=version(), ext_modules=[Extension("specula._specula", sources=[])], cmdclass={"build_ext": CMakeBuild})

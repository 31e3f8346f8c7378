"""Build hook: the shipped weights go into the wheel.

The weights and their model cards live in the repository's top-level ``models/`` folder (where a source
checkout and an editable install read them). A wheel has no such folder, so building one copies them into
the package as ``cuboidcli/models/``, where :mod:`cuboidcli.weights` looks first. Everything else about the
package is declared in pyproject.toml.
"""

from pathlib import Path

from setuptools import setup
from setuptools.command.build_py import build_py

MODELS = Path(__file__).resolve().parent / "models"
#: What is shipped: every weights file and model card (the defaults and those the documentation names).
SHIPPED = ("*.pt", "*.md", "neural/*.pt", "neural/*.md", "rgb/*.pt", "rgb/*.md")


def shipped_files() -> list[Path]:
    return sorted({p for pattern in SHIPPED for p in MODELS.glob(pattern) if p.is_file()})


class BuildPyWithModels(build_py):
    """``build_py`` that also copies ``models/`` to ``<build>/cuboidcli/models/`` (not for editable
    installs, which read the top-level folder itself)."""

    def run(self) -> None:
        super().run()
        if getattr(self, "editable_mode", False):
            return
        for src in shipped_files():
            dst = Path(self.build_lib) / "cuboidcli" / "models" / src.relative_to(MODELS)
            self.mkpath(str(dst.parent))
            self.copy_file(str(src), str(dst))

    def get_outputs(self, include_bytecode: bool = True) -> list[str]:
        outputs = super().get_outputs(include_bytecode)
        if getattr(self, "editable_mode", False):
            return outputs
        base = Path(self.build_lib) / "cuboidcli" / "models"
        return outputs + [str(base / p.relative_to(MODELS)) for p in shipped_files()]


setup(cmdclass={"build_py": BuildPyWithModels})

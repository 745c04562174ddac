"""Prints the Python package's runtime and `test`-extra requirements from
pyproject.toml, one per line, with the package's own extras expanded, for
`pip install` in .ci/test (which tests the bindings without building a wheel)."""

import re
import sys
from pathlib import Path

PYPROJECT = Path(__file__).resolve().parents[1] / "pyproject.toml"

if sys.version_info >= (3, 11):
    import tomllib
else:  # Python 3.9 and 3.10: pip's own vendored TOML reader.
    from pip._vendor import tomli as tomllib

project = tomllib.loads(PYPROJECT.read_text())["project"]
extras = project.get("optional-dependencies", {})
name = project["name"]


def expand(requirements):
    for requirement in requirements:
        own = re.fullmatch(rf"{re.escape(name)}\[([^\]]+)\]", requirement.strip())
        if own:
            for extra in own.group(1).split(","):
                yield from expand(extras[extra.strip()])
        else:
            yield requirement


for requirement in [*project.get("dependencies", []), *expand(extras["test"])]:
    print(requirement)

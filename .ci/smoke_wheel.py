"""Smoke test of a release: the sdist and wheel in DIST hold what a user needs, and the
wheel, installed (not editable) into the virtualenv whose python runs this script, makes and
steps every Gymnasium id and answers `franka-composer --version` and each command's
`--help` (every module the commands import is in the wheel).

Run it with that python, isolated (`-I`), from outside the checkout, so that the package
imported is the installed wheel and never the source tree:

    cd /tmp && VENV/bin/python -I REPO/.ci/smoke_wheel.py REPO/dist
"""

from __future__ import annotations

import pathlib
import subprocess
import sys
import sysconfig
import tarfile
import zipfile

#: Files every sdist holds beside the package, and those it holds where the checkout has
#: them (MANIFEST.in).
SDIST_FILES = ("setup.cfg", "pyproject.toml", "README.md", "MANIFEST.in",
               "franka_composer/__init__.py", "franka_composer/py.typed")
REQUIRED_IF_PRESENT = ("LICENSE", "NOTICE", "CHANGELOG.md", "CITATION.cff")
#: Folders the sdist leaves out: the test suite reads the checkout's results/, docs/ and
#: benchmarks/, so a part of it in the sdist could not run (setuptools adds tests/test*.py
#: by default, without conftest.py).
SDIST_LEFT_OUT = ("tests/",)
#: Files the wheel holds (PEP 561's marker: the type hints reach users' type checkers).
WHEEL_FILES = ("franka_composer/__init__.py", "franka_composer/py.typed")


def one(dist: pathlib.Path, pattern: str) -> pathlib.Path:
    found = sorted(dist.glob(pattern))
    if len(found) != 1:
        raise SystemExit(f"{dist}: expected one {pattern}, found {[p.name for p in found]}")
    return found[0]


def missing_from_archives(dist: pathlib.Path, checkout: pathlib.Path) -> list[str]:
    """What the sdist and the wheel in `dist` lack, as 'archive: file' lines, and what the
    sdist holds of the folders it leaves out ('archive: holds file')."""
    sdist, wheel = one(dist, "*.tar.gz"), one(dist, "*.whl")
    with tarfile.open(sdist) as archive:
        # Members are "<name>-<version>/<path>".
        in_sdist = {member.split("/", 1)[1] for member in archive.getnames() if "/" in member}
    with zipfile.ZipFile(wheel) as archive:
        in_wheel = set(archive.namelist())
    wanted = list(SDIST_FILES) + [name for name in REQUIRED_IF_PRESENT
                                  if (checkout / name).exists()]
    return ([f"{sdist.name}: {name}" for name in wanted if name not in in_sdist]
            + [f"{wheel.name}: {name}" for name in WHEEL_FILES if name not in in_wheel]
            + [f"{sdist.name}: holds {name}" for name in sorted(in_sdist)
               if name.startswith(SDIST_LEFT_OUT)])


def check_installed_wheel() -> str:
    """Imports the installed package, makes and steps every id; returns its version."""
    import gymnasium as gym

    import franka_composer

    package = pathlib.Path(franka_composer.__file__).resolve().parent
    site = pathlib.Path(sysconfig.get_paths()["purelib"]).resolve()
    if site not in package.parents:
        raise SystemExit(f"imported {package}, not the wheel installed in {site}")
    if not (package / "py.typed").is_file():
        raise SystemExit(f"{package} has no py.typed")
    for id_ in franka_composer.ENV_IDS:
        env = gym.make(id_)
        observation, _ = env.reset(seed=0)
        observation, reward, terminated, truncated, info = env.step(env.action_space.sample())
        if not env.observation_space.contains(observation) or not {
                "is_success"} <= set(info):
            raise SystemExit(f"{id_}: a step's observation or info is not as specified")
        env.close()
    print(f"made, reset and stepped {len(franka_composer.ENV_IDS)} ids")
    return franka_composer.__version__


def main(argv: list[str]) -> int:
    if len(argv) != 1:
        raise SystemExit(f"usage: python -I {__file__} DIST")
    dist = pathlib.Path(argv[0]).resolve()
    missing = missing_from_archives(dist, checkout=pathlib.Path(__file__).resolve().parents[1])
    if missing:
        raise SystemExit("missing from the release (or held where it should not be):\n"
                         + "\n".join(missing))
    version = check_installed_wheel()
    command = pathlib.Path(sys.executable).parent / "franka-composer"
    printed = subprocess.run([str(command), "--version"], capture_output=True, text=True,
                             check=True).stdout
    if printed != f"franka-composer {version}\n":
        raise SystemExit(f"franka-composer --version printed {printed!r}, not {version}")
    from franka_composer.cli import SUBCOMMANDS

    for name in SUBCOMMANDS:
        answered = subprocess.run([str(command), name, "--help"], capture_output=True,
                                  text=True)
        if answered.returncode != 0 or not answered.stdout.startswith(
                f"usage: franka-composer {name}"):
            raise SystemExit(f"franka-composer {name} --help failed: {answered.stderr[-500:]}")
    print(f"franka-composer {', '.join(SUBCOMMANDS)}: each answers --help")
    print(f"the wheel and sdist in {dist} pass: franka-composer {version}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))

"""Where the Menagerie Panda comes from.

The Panda is never vendored: it is resolved through the `mujoco-menagerie` package, which
downloads and caches Menagerie models on first use, or reads a local checkout named by the
`MENAGERIE_ROOT` environment variable (the only option on machines without internet).
"""

from __future__ import annotations

import functools
import pathlib

PANDA_NAME = "franka_emika_panda"


class MenagerieUnavailableError(RuntimeError):
    """The Panda could be neither downloaded nor found under MENAGERIE_ROOT: nothing can be
    built, and the message says what to set."""


@functools.lru_cache(maxsize=None)
def panda_dir() -> pathlib.Path:
    """The folder holding Menagerie's `franka_emika_panda` (panda.xml and its meshes)."""
    import mujoco_menagerie  # Deferred: resolving may download on first use.

    try:
        return mujoco_menagerie.get(PANDA_NAME).path()
    except mujoco_menagerie.MenagerieError as error:
        raise MenagerieUnavailableError(
            f"Could not resolve Menagerie's {PANDA_NAME!r}: {error}. Set MENAGERIE_ROOT to a "
            "folder that contains franka_emika_panda/ (a Menagerie checkout) when offline."
        ) from error


def panda_in_cache() -> bool:
    """Whether mujoco-menagerie's own cache already holds the Panda, so that nothing needs
    downloading and no MENAGERIE_ROOT is needed (the Makefile's test before it sets one)."""
    import mujoco_menagerie

    return mujoco_menagerie.Cache().is_cached(mujoco_menagerie.get(PANDA_NAME))


def panda_xml() -> pathlib.Path:
    """Menagerie's arm-and-hand model file."""
    return panda_dir() / "panda.xml"

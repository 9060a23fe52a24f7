"""Where the Panda comes from: mujoco-menagerie's cache, or MENAGERIE_ROOT."""

from __future__ import annotations

import mujoco_menagerie
from mujoco_menagerie._cache import SENTINEL

from franka_composer.assets import PANDA_NAME, panda_in_cache


def test_the_panda_is_in_the_cache_once_menagerie_has_published_it_there(tmp_path,
                                                                         monkeypatch):
    """An empty cache has no Panda, whatever MENAGERIE_ROOT says; a cache in which
    mujoco-menagerie's publish marker stands for the Panda's folder has it."""
    monkeypatch.setenv("MENAGERIE_CACHE_DIR", str(tmp_path))
    assert not panda_in_cache()
    published = mujoco_menagerie.Cache().model_path(mujoco_menagerie.get(PANDA_NAME))
    published.mkdir(parents=True)
    (published / SENTINEL).touch()
    assert panda_in_cache()

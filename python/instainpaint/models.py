"""The learned networks instainpaint uses when they are in the cache (`instainpaint models`).

    import instainpaint as ii

    ii.models.get("mobile-sam")          # downloads it once, checks its checksum, returns its path
    ii.models.path("big-lama")           # the verified file, or an Error saying how to bring it
    [n["name"] for n in ii.models.list()["networks"]]

Once in the cache, Predictor(), Segmenter(), select(), Gaussians.select() and predict()'s
inpainter use them by default ("auto"), as the commands do. The cache: $INSTAINPAINT_MODELS_DIR,
else $XDG_CACHE_HOME/instainpaint/models, else ~/.cache/instainpaint/models. Nothing is
downloaded but by get().
"""
from __future__ import annotations

import json
import os
from typing import Any, Dict, Optional, Union

from . import _core

PathLike = Union[str, "os.PathLike[str]"]


def get(name: str, *, mirror: Optional[str] = None, timeout: float = 30.0, progress: bool = True) -> str:
    """The network `name` of the catalogue (instainpaint, mobile-sam, sam-vit-b, sam-vit-l,
    sam-vit-h, big-lama) in the cache: downloaded (or resumed) and checked when it is not there yet.
    mirror: a base URL holding the same file names (default $INSTAINPAINT_MODELS_MIRROR, else where
    the authors publish it). Returns the file's path."""
    return _core._models_get(name, mirror or "", float(timeout), bool(progress))


def path(name: str) -> str:
    """The verified file of `name` in the cache; raises Error (with the command that brings it) when absent."""
    return _core._models_path(name)


def list() -> Dict[str, Any]:  # noqa: A001 - the command's name
    """`instainpaint models list --json`: the folder, each network with its state, and what "auto" picks."""
    return json.loads(_core._models_list())


def import_file(file: PathLike, name: str) -> str:
    """A file downloaded by hand, checked as a download is and copied into the cache as `name`."""
    return _core._models_import(os.fspath(file), name)


def remove(name: str) -> bool:
    """Deletes `name` from the cache; whether anything was there."""
    return _core._models_remove(name)

"""Shared fixtures: the real statue scene from ../shared and the CLI of the same build."""
import os
import pathlib

import pytest

REPO = pathlib.Path(__file__).resolve().parents[2]

# The tests run with an empty models' cache of their own: a network a developer fetched
# (instainpaint models get) must not change what they run. Set before the library reads it.
os.environ["INSTAINPAINT_MODELS_DIR"] = str(pathlib.Path(__import__("tempfile").mkdtemp(prefix="ii-py-models-")))
for _name in ("INSTAINPAINT_MODELS_CATALOGUE", "INSTAINPAINT_MODELS_MIRROR", "INSTAINPAINT_SEGMENTER",
              "INSTAINPAINT_INPAINTER"):
    os.environ.pop(_name, None)


@pytest.fixture(scope="session")
def shared() -> pathlib.Path:
    return pathlib.Path(os.environ.get("INSTAINPAINT_SHARED", REPO.parent / "shared"))


def shared_data(shared: pathlib.Path, folder: str) -> pathlib.Path:
    """The shared data folder, or a skip: as in the C++ tests, a folder counts only when it holds
    its PROVENANCE.md (an emptied one is as absent as a removed one)."""
    path = shared / "data" / folder
    if not (path / "PROVENANCE.md").is_file():
        pytest.skip(f"shared data missing: {path} is absent or incomplete (no PROVENANCE.md)")
    return path


@pytest.fixture(scope="session")
def statue_dir(shared) -> pathlib.Path:
    return shared_data(shared, "statue")


@pytest.fixture(scope="session")
def cli() -> pathlib.Path:
    path = pathlib.Path(os.environ.get("INSTAINPAINT_CLI", REPO / "build" / "instainpaint"))
    if not path.is_file():
        pytest.fail(f"the command-line program is missing: {path} (make build, or set INSTAINPAINT_CLI)")
    return path


@pytest.fixture(scope="session")
def statue(statue_dir):
    import instainpaint
    return instainpaint.load_scene(statue_dir)


@pytest.fixture(scope="session")
def predictor():
    import instainpaint
    # fp32: the same numbers on every CPU (bf16 depends on the CPU's instructions)
    return instainpaint.Predictor(device="cpu", precision="fp32")

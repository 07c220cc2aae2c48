"""Test-only node types and a CLI runner for the core tests (conftest.py adds the types to a test registry)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

from pydantic import BaseModel, ConfigDict, Field

from flowmc.errors import NodeError
from flowmc.registry import In, NodeType, Out

REPO = Path(__file__).resolve().parents[2]


class Blob:
    """A stand-in value type with the digest()/summary() contract (a Path-typed port value)."""

    def __init__(self, label: str):
        self.label = label

    def digest(self) -> str:
        return "blob:" + self.label

    def summary(self) -> dict:
        return {"type": "Blob", "label": self.label}


class BlobParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    label: str = Field("x", description="label")
    feed: float = Field(10.0, gt=0, description="feed, mm/s")


class BlobSource(NodeType):
    type_id = "test.blob"
    title = "Blob"
    category = "Test"
    description = "Makes a Blob (Path-typed)."
    Params = BlobParams
    outputs = (Out("path", "Path", doc="the blob"), Out("feed", "Number", doc="the feed"))

    def run(self, ctx, params):
        return {"path": Blob(params.label), "feed": params.feed}


class BlobSink(NodeType):
    type_id = "test.sink"
    title = "Sink"
    category = "Test"
    description = "Takes a Path or a Trajectory and reports its label length."
    inputs = (In("path", ("Path", "Trajectory"), doc="blob"),)
    outputs = (Out("n", "Number", doc="label length"),)

    def run(self, ctx, params, path):
        return {"n": float(len(path.label))}


class Boom(NodeType):
    type_id = "test.boom"
    title = "Boom"
    category = "Test"
    description = "Always fails with a plain exception."
    inputs = (In("value", "Number", doc="ignored", default=0.0),)
    outputs = (Out("value", "Number", doc="never"),)

    def run(self, ctx, params, value):
        raise ZeroDivisionError("boom from the test node")


class Clock(NodeType):
    type_id = "test.clock"
    title = "Clock"
    category = "Test"
    description = "A side-effect node: never cached."
    pure = False
    outputs = (Out("value", "Number", doc="constant"),)

    def run(self, ctx, params):
        return {"value": 1.0}


class ReadParams(BaseModel):
    model_config = ConfigDict(extra="forbid")
    file: str = Field("data.txt", description="file to read")


class ReadText(NodeType):
    type_id = "test.read"
    title = "Read"
    category = "Test"
    description = "Reads a text file through ctx.resolve."
    pure = False
    Params = ReadParams
    outputs = (Out("text", "Text", doc="contents"),)

    def run(self, ctx, params):
        path = ctx.resolve(params.file)
        if not path.is_file():
            raise NodeError(f"no file {params.file!r}")
        return {"text": path.read_text()}


TEST_TYPES = (BlobSource, BlobSink, Boom, Clock, ReadText)


def run_cli(*args: str, cwd: Path | None = None) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "flowmc", *args], cwd=cwd, capture_output=True, text=True, timeout=120)

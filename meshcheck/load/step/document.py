"""STEP bytes -> OpenCASCADE's document of placed solids, and the messages OpenCASCADE prints.

OpenCASCADE's XCAF reader (``STEPCAFControl_Reader``, through the OCP bindings) reads the file
into a document of products and instances; its assembly structure is checked before anything is
transferred (``assembly.check_structure``), and every solid must be in a placed product after.

OpenCASCADE prints its diagnostics on the process's standard output and error streams (file
descriptors 1 and 2), where the report goes. They are captured while it runs
(``captured_output``), and the first error line becomes the reason of the ``InputError`` for a
broken file.
"""

from __future__ import annotations

import contextlib
import os
import re
import sys
import tempfile
from collections.abc import Callable, Iterator

from ...errors import InputError
from .assembly import Instance, check_all_solids_placed, check_structure, walk


def read_document(data: bytes, path: str) -> list[Instance]:
    """Read, check and transfer ``data`` (the content of ``path``): every solid instance.

    Raises
    ------
    InputError
        ``data`` is not STEP OpenCASCADE can read (the reason is its first error line), its
        assembly structure is broken (``check_structure``), or a solid is in no placed product
        (``check_all_solids_placed``).
    """
    from OCP.IFSelect import IFSelect_ReturnStatus
    from OCP.STEPCAFControl import STEPCAFControl_Reader
    from OCP.TCollection import TCollection_ExtendedString
    from OCP.TDocStd import TDocStd_Document

    doc = TDocStd_Document(TCollection_ExtendedString("XmlOcaf"))
    with tempfile.TemporaryDirectory() as tmp, captured_output() as messages:
        # Read the bytes hashed (a file changing under us cannot give another file's parts).
        copy = os.path.join(tmp, "input.step")
        with open(copy, "wb") as f:
            f.write(data)
        reader = STEPCAFControl_Reader()
        reader.SetNameMode(True)
        is_read = reader.ReadFile(copy) == IFSelect_ReturnStatus.IFSelect_RetDone
        if is_read:
            counts = check_structure(reader.Reader().StepModel(), path)
            is_read = reader.Transfer(doc)
    if not is_read:  # the messages are read back once the streams are restored
        raise InputError(path, f"cannot be read as STEP: {_first_error(messages())}")
    instances = walk(doc)
    check_all_solids_placed(instances, counts, path)
    return instances


@contextlib.contextmanager
def captured_output() -> Iterator[Callable[[], str]]:
    """Send file descriptors 1 and 2 to a temporary file; yield a function reading it back."""
    with tempfile.TemporaryFile() as sink:
        for stream in (sys.stdout, sys.stderr):
            with contextlib.suppress(Exception):
                stream.flush()
        saved = [os.dup(1), os.dup(2)]
        try:
            os.dup2(sink.fileno(), 1)
            os.dup2(sink.fileno(), 2)
            text: list[str] = []

            def read() -> str:
                return "".join(text)

            yield read
        finally:
            os.dup2(saved[0], 1)
            os.dup2(saved[1], 2)
            os.close(saved[0])
            os.close(saved[1])
            sink.seek(0)
            text.append(sink.read(1 << 16).decode("utf-8", "replace"))


def _first_error(messages: str) -> str:
    """The first error line OpenCASCADE printed, without colours and decoration."""
    clean = re.sub(r"\x1b\[[0-9;]*m", "", messages)
    lines = [line.strip(" *\t") for line in clean.splitlines()]
    errors = [line for line in lines if "ERR" in line or "rror" in line]
    if not errors:
        return "not a STEP file OpenCASCADE can read"
    # "**** ERR StepFile : Undefined Parsing: Line 7: Incorrect syntax: ..." -> "Line 7: ..."
    reason = re.sub(r"^ERR\s+StepFile\s*:\s*(Undefined Parsing\s*:\s*)?", "", errors[0])
    return _one_line(reason)


def _one_line(text) -> str:
    text = " ".join(str(text).split()) or "unknown error"
    text = "".join(c if c.isprintable() else "?" for c in text)
    return text if len(text) <= 160 else text[:157] + "..."

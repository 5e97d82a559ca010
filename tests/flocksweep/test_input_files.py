"""Input files are checked before they are read (docs/errors.md): a FIFO, a device, a folder or an
oversized file is refused as bad input (exit 2) naming the file, never read (a FIFO would block, a
device never end), and the refusals of tests/malformed.py's SIZES, SPECIAL_FILES, NUMBERS, TABLES and
EXPRESSIONS (each once a traceback, a hang or a silent acceptance) hold."""
from __future__ import annotations

import os

import pytest

from flocksweep.cli import main
from malformed import EXPRESSIONS, NUMBERS, SIZES, SPECIAL_FILES, TABLES, attempt
from flocksweep.simcore.schema import ConfigError, read_input


def test_a_fifo_as_sweep_file_is_refused_without_blocking(tmp_path, capsys):
    fifo = tmp_path / "s.toml"
    os.mkfifo(fifo)                     # nobody writes to it: reading it would block forever
    assert main(["run", str(fifo), "--out", str(tmp_path / "out")]) == 2
    assert "s.toml is not a regular file (a FIFO, device or socket)" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_reads_are_bounded(tmp_path):
    big = tmp_path / "big.toml"
    big.write_bytes(b"#" * 2048)
    with pytest.raises(ConfigError, match="holds 2,048 bytes; at most 1,024"):
        read_input(big, "x", "the file", 1024)
    assert read_input(big, "x", "the file", 4096) == b"#" * 2048


def test_a_symlink_loop_is_refused_naming_it(tmp_path):
    loop = tmp_path / "loop.toml"
    loop.symlink_to(loop)
    with pytest.raises(ConfigError, match="cannot be read: .*loop.toml: Too many levels of symbolic links"):
        read_input(loop, "x", "sweep file", 1024)


@pytest.mark.parametrize("case", SIZES + SPECIAL_FILES + NUMBERS + TABLES + EXPRESSIONS, ids=lambda c: c.name)
def test_sizes_files_numbers_tables_and_expressions_are_refused_before_anything_is_written(case, tmp_path):
    result = attempt(case, tmp_path)
    assert result.clean(case), (result.code, result.crash or result.stderr)

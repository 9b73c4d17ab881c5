"""Fixed-point text of program lines (ftsweep.stages.numerics.decimals): digit for digit what
Python's ``format(v, ".9f")`` prints, and the numbers read back from it, on random, tied
(dyadic halves of the last decimal) and extreme values."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from ftsweep.exports.files import DataLines
from ftsweep.stages.numerics import decimals


def _python(values: np.ndarray, d: int) -> str:
    return "\n".join(" ".join(format(v, f".{d}f") for v in row) for row in values.tolist())


def _read(values: np.ndarray, d: int) -> np.ndarray:
    return np.array([[float(format(v, f".{d}f")) for v in row] for row in values.tolist()]).reshape(
        values.shape
    )


def _same(a: np.ndarray, b: np.ndarray) -> bool:
    return bool(np.array_equal(a, b) and np.array_equal(np.signbit(a), np.signbit(b)))


_finite = st.floats(allow_nan=False, allow_infinity=False, min_value=-4.0e9, max_value=4.0e9)


@settings(max_examples=300, deadline=None)
@given(st.lists(st.tuples(_finite, _finite, _finite), min_size=1, max_size=20), st.integers(1, 9))
def test_text_and_read_back_are_pythons(rows, d):
    values = np.array(rows, dtype=np.float64)
    values = np.where(np.abs(values) * 10**d < decimals.LIMIT, values, 0.0)
    assert decimals.rows_text(values, d) == _python(values, d)
    assert _same(decimals.printed(values, d), _read(values, d))


@settings(max_examples=300, deadline=None)
@given(st.integers(-(2**40), 2**40), st.integers(0, 45), st.integers(1, 9))
def test_ties_round_half_to_even(k, shift, d):
    # k/2^shift are the doubles whose scaled value can end exactly in a half unit (e.g.
    # 1/1024 = 0.0009765625: 976562.5 units of 1e-9, printed ...562)
    values = np.array([[k / 2.0**shift, -k / 2.0**shift]])
    values = np.where(np.abs(values) * 10**d < decimals.LIMIT, values, 0.0)
    assert decimals.rows_text(values, d) == _python(values, d)
    assert _same(decimals.printed(values, d), _read(values, d))


def test_extreme_and_signed_values():
    values = np.array(
        [
            [0.0, -0.0, 1 / 1024, -1 / 1024],
            [0.5e-9, -0.5e-9, 1.5e-9, 2.5e-9],
            [5e-324, -1e-300, 9.007e6, 123456789.123456789],
            [4.6e9, -4.6e9, 2.0**53 / 1e9, -(2.0**53 + 2.0) / 1e9],
        ]
    )
    assert decimals.rows_text(values, 9) == _python(values, 9)
    assert _same(decimals.printed(values, 9), _read(values, 9))


def test_many_values_as_in_a_program():
    rng = np.random.default_rng(7)
    n = 20_000
    values = np.column_stack(
        [
            np.cumsum(rng.random(n)) * 1e-3,
            np.cumsum(rng.random(n)) * 37.0,
            rng.random(n) * 30.0,
            rng.normal(0, 1e-3, n),
        ]
    )
    assert decimals.rows_text(values, 9) == _python(values, 9)
    assert _same(decimals.printed(values, 9), _read(values, 9))


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf, 5.0e9])
def test_unwritable_values_are_named(bad):
    values = np.array([[1.0, 2.0], [3.0, bad]])
    with pytest.raises(ValueError, match=r"row 1, column 1: .* cannot be written with 9 decimals"):
        decimals.rows_text(values, 9)


def test_data_lines_are_the_joined_lines_as_ascii():
    values = np.array([[1.0, -2.5, 3.25e-10], [4.0, 5.0, -6.0]])
    lines = DataLines(values)
    assert len(lines) == 2
    assert lines.encoded == b"1.000000000 -2.500000000 0.000000000\n4.000000000 5.000000000 -6.000000000"
    assert DataLines(np.empty((0, 3))).encoded == b""


@pytest.mark.parametrize("ending", ["\n", "", "\n\n"])
def test_file_crc_is_over_its_lines_but_the_crc_line(ending):
    # read_program_file takes the CRC from the file's bytes around the CRC line; it must be
    # crc_of the rows without it, whatever the file's ending and its header's characters
    from ftsweep.exports import files

    rows = ["# magic", "# tool: nose radius 83 µm", "# CRC32: 0x00000000", "a_b c_d", "1.0 2.0", "3.0 4.0"]
    raw = ("\n".join(rows) + ending).encode("utf-8")
    read = raw.decode("utf-8").split("\n")
    if read[-1] == "":
        read = read[:-1]
    assert files._crc_without(raw, read, 2) == files.crc_of([r for i, r in enumerate(read) if i != 2])


def _loadtxt(text: str, cols: int) -> np.ndarray:
    return np.loadtxt(text.split("\n"), dtype=np.float64, delimiter=" ", comments=None, ndmin=2).reshape(
        -1, cols
    )


@settings(max_examples=300, deadline=None)
@given(
    st.lists(st.tuples(_finite, _finite, _finite), min_size=1, max_size=20),
    st.integers(1, 9),
    st.integers(1, 9),
)
def test_lines_as_written_are_read_as_any_reader_reads_them(rows, d, read_d):
    # the compiled reader gives each printed decimal's nearest double, as loadtxt does; a
    # number of 2^53 units or more, or more decimals than it reads, is left to the general
    # reader (None)
    values = np.where(np.abs(np.array(rows)) * 10**d < decimals.LIMIT, np.array(rows), 0.0)
    text = decimals.rows_text(values, d)
    got = decimals.parse_rows(text.encode("ascii"), 3, read_d)
    units = np.abs(np.round(decimals.printed(values, d) * 10**read_d))
    if d > read_d or np.any(units >= 2**53):
        assert got is None
    else:
        assert got is not None and _same(got, _loadtxt(text, 3))
        assert _same(got, decimals.printed(values, d))


@pytest.mark.parametrize(
    "text",
    [
        "1.0 2.0\n3.0",  # a short row
        "1.0 2.0\n3.0 4.0\n",  # a blank last line
        "1.0  2.0",  # two spaces
        "1.0 2.0\r\n3.0 4.0",  # a carriage return
        "1e-3 2.0",  # an exponent
        "+1.0 2.0",  # a plus sign
        ".5 2.0",  # no whole part
        "5. 2.0",  # no decimals
        "1.0 2.0 3.0",  # a third number
        "1.0,2.0",  # another separator
        "nan 2.0",
        "1.0000000001 2.0",  # ten decimals
        "9007199.254740992 1.0",  # 2^53 units
    ],
)
def test_other_text_is_left_to_the_general_reader(text):
    assert decimals.parse_rows(text.encode("ascii"), 2, 9) is None


def _program(folder: Path, lines: list[str], end: str = "\n") -> Path:
    """A program file of header rows and ``lines`` after the column line, its CRC right."""
    from ftsweep.exports import files

    rows = ["# magic", "# a: b"]
    crc = files.crc_of([*rows, "x_mm y_mm", *lines])
    out = folder / "p.txt"
    out.write_bytes(
        "\n".join([*rows, files.CRC_LINE.format(crc), "x_mm y_mm", *lines]).encode() + end.encode()
    )
    return out


def test_program_files_are_read_as_written(tmp_path):
    from ftsweep.exports import files

    written = files.read_program_file(
        _program(tmp_path, ["1.500000000 -0.000000000", "2.000000000 3.250000000"]), "# magic", "x_mm y_mm"
    )
    assert _same(written.data, np.array([[1.5, -0.0], [2.0, 3.25]]))
    assert written.fields["a"] == "b" and written.fields["CRC32"].startswith("0x")


@pytest.mark.parametrize(
    ("second", "column"),
    [
        ("4e0 3.250000000", 2),  # an exponent
        ("+2.000000000 3.250000000", 1),  # a plus sign
        ("3.340010000e-4 3.250000000", 12),  # an exponent after the digits
        ("02.000000000 3.250000000", 2),  # a leading zero
        ("2.00000000 3.250000000", 11),  # eight decimals
        ("2.000000000  3.250000000", 13),  # two spaces
        ("2.000000000 x", 13),
        ("2.000000000 inf", 13),
        ("2.000000000", 12),  # a short line
    ],
)
def test_program_data_lines_other_than_exports_are_refused_by_line_and_column(tmp_path, second, column):
    # what a controller reads must be what export wrote, byte for byte: no other spelling of a number
    from ftsweep.exports import files

    path = _program(tmp_path, ["1.500000000 -0.000000000", second])
    with pytest.raises(files.ProgramError, match=f"line 6, column {column}: a data line"):
        files.read_program_file(path, "# magic", "x_mm y_mm")


@pytest.mark.parametrize(
    ("lines", "end", "message"),
    [
        (
            ["1.500000000 -0.000000000", "2.000000000 3.250000000"],
            "\r\n",
            "line 6, column 24 holds a carriage",
        ),
        (["1.500000000 -0.000000000\r2.000000000 3.250000000"], "\n", "line 5, column 25 holds a carriage"),
        (["1.500000000 -0.000000000", "", "2.000000000 3.250000000"], "\n", "line 6, column 1 is blank"),
        (["1.500000000 -0.000000000"], "", "no line end"),
        (["1.500000000 -0.000000000\t"], "\n", "byte 0x09"),
    ],
)
def test_line_ends_other_than_exports_are_refused(tmp_path, lines, end, message):
    # every CR, LF or CRLF ends a line on some controller: only export's LF is accepted
    from ftsweep.exports import files

    with pytest.raises(files.ProgramError, match=message):
        files.read_program_file(_program(tmp_path, lines, end), "# magic", "x_mm y_mm")


def test_a_program_without_data_lines_reads_empty(tmp_path):
    from ftsweep.exports import files

    assert files.read_program_file(_program(tmp_path, []), "# magic", "x_mm y_mm").data.shape == (0, 2)

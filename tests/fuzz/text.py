"""Mutations of a text table: rows and cells (``CSV_OPS``), bytes and lines (``TEXT_OPS``)."""

from __future__ import annotations

import contextlib

from hypothesis import strategies as st

from . import BAD_CELLS, UNICODE_TEXT

CSV_OPS = st.one_of(
    st.tuples(
        st.just("cell"), st.integers(0, 10_000), st.integers(0, 20), st.sampled_from(BAD_CELLS)
    ),
    st.tuples(st.just("unicode_cell"), st.integers(0, 10_000), st.integers(0, 20), UNICODE_TEXT),
    st.tuples(st.just("drop_col"), st.integers(0, 20)),
    st.tuples(
        st.just("extra_col"),
        st.sampled_from(["note", "Theta", "x y", "t", "é", ""]),
        st.sampled_from(["1", "", "nan", "abc"]),
    ),
    st.tuples(st.just("ragged"), st.integers(0, 10_000), st.booleans()),
    st.tuples(st.just("dup_row"), st.integers(0, 10_000)),
    st.tuples(st.just("swap_rows"), st.integers(0, 10_000), st.integers(0, 10_000)),
    st.tuples(st.just("reverse")),
    st.tuples(
        st.just("scale_col"), st.integers(0, 20), st.sampled_from([1e300, 1e-300, -1.0, 0.0, 1e15])
    ),
    st.tuples(st.just("jitter_t"), st.integers(0, 10_000), st.floats(-0.9, 0.9)),
    st.tuples(st.just("rename_header"), st.integers(0, 20), UNICODE_TEXT),
    st.tuples(st.just("upper_header")),
    st.tuples(st.just("dup_header"), st.integers(0, 20), st.integers(0, 20)),
    st.tuples(st.just("drop_rows"), st.integers(0, 60)),
    st.tuples(st.just("const_col"), st.integers(0, 20), st.sampled_from(["0", "0.5", "1e-20"])),
)
TEXT_OPS = st.one_of(
    st.tuples(st.just("bom")),
    st.tuples(st.just("crlf")),
    st.tuples(st.just("cr")),
    st.tuples(st.just("blank_lines"), st.integers(0, 10_000)),
    st.tuples(st.just("comment"), st.integers(0, 10_000), UNICODE_TEXT),
    st.tuples(st.just("truncate"), st.floats(0.0, 1.0)),
    st.tuples(st.just("nul"), st.floats(0.0, 1.0)),
    st.tuples(
        st.just("latin1"),
    ),
    st.tuples(st.just("flip_byte"), st.floats(0.0, 1.0), st.integers(0, 255)),
    st.tuples(st.just("no_final_newline")),
    st.tuples(st.just("trailing_delim")),
    st.tuples(st.just("quote_all")),
    st.tuples(st.just("quote_cells")),
    st.tuples(st.just("spaces")),
)


def apply_row_ops(header: list[str], rows: list[list[str]], ops) -> None:
    for op in ops:
        kind = op[0]
        if kind in ("cell", "unicode_cell") and rows:
            r = op[1] % len(rows)
            if rows[r]:
                rows[r][op[2] % len(rows[r])] = op[3]
        elif kind == "drop_col" and header:
            c = op[1] % len(header)
            del header[c]
            for row in rows:
                if c < len(row):
                    del row[c]
        elif kind == "extra_col":
            header.append(op[1])
            for row in rows:
                row.append(op[2])
        elif kind == "ragged" and rows:
            row = rows[op[1] % len(rows)]
            if op[2]:
                row.append("0")
            elif row:
                row.pop()
        elif kind == "dup_row" and rows:
            r = op[1] % len(rows)
            rows.insert(r, list(rows[r]))
        elif kind == "swap_rows" and rows:
            a, b = op[1] % len(rows), op[2] % len(rows)
            rows[a], rows[b] = rows[b], rows[a]
        elif kind == "reverse":
            rows.reverse()
        elif kind == "scale_col" and header:
            c = op[1] % len(header)
            for row in rows:
                with contextlib.suppress(ValueError, IndexError):
                    row[c] = repr(float(row[c]) * op[2])
        elif kind == "jitter_t" and "t" in header and rows:
            c = header.index("t")
            row = rows[op[1] % len(rows)]
            with contextlib.suppress(ValueError, IndexError):
                row[c] = repr(float(row[c]) + op[2] * 0.01)
        elif kind == "rename_header" and header:
            header[op[1] % len(header)] = op[2]
        elif kind == "upper_header":
            header[:] = [h.upper() if h != "run" else h for h in header]
        elif kind == "dup_header" and header:
            header[op[2] % len(header)] = header[op[1] % len(header)]
        elif kind == "drop_rows":
            del rows[op[1] :]
        elif kind == "const_col" and header:
            c = op[1] % len(header)
            for row in rows:
                if c < len(row):
                    row[c] = op[2]


def apply_text_ops(text: str, delim: str, ops) -> bytes:
    data: bytes | None = None
    for op in ops:
        kind = op[0]
        if (
            kind
            in (
                "bom",
                "crlf",
                "cr",
                "blank_lines",
                "comment",
                "no_final_newline",
                "trailing_delim",
                "spaces",
            )
            and data is None
        ):
            lines = text.split("\n")
            if kind == "bom":
                text = "\ufeff" + text
            elif kind == "crlf":
                text = text.replace("\n", "\r\n")
            elif kind == "cr":
                text = text.replace("\n", "\r")
            elif kind == "blank_lines":
                i = op[1] % len(lines)
                lines.insert(i, "   ")
                text = "\n".join(lines)
            elif kind == "comment":
                i = op[1] % len(lines)
                lines.insert(i, "# " + " ".join(op[2].split()))
                text = "\n".join(lines)
            elif kind == "no_final_newline":
                text = text.rstrip("\n")
            elif kind == "trailing_delim":
                d = "," if delim == " " else delim
                text = "\n".join(line + d if line else line for line in lines)
            elif kind == "spaces" and delim != " ":
                text = "\n".join(
                    (delim + " ").join(line.split(delim)) if line else line for line in lines
                )
        elif kind == "quote_all" and data is None:
            text = "\n".join('"' + line + '"' if line else line for line in text.split("\n"))
        else:
            if data is None:
                data = text.encode("utf-8")
            if kind == "truncate":
                data = data[: int(op[1] * len(data))]
            elif kind == "nul" and data:
                i = int(op[1] * (len(data) - 1))
                data = data[:i] + b"\x00" + data[i:]
            elif kind == "latin1":
                data = text.encode("latin-1", errors="replace") + "é".encode("latin-1")
            elif kind == "flip_byte" and data:
                i = int(op[1] * (len(data) - 1))
                data = data[:i] + bytes([op[2]]) + data[i + 1 :]
    return data if data is not None else text.encode("utf-8")

"""Whether the bytes of a cached library are a whole ELF shared library that defines the
symbols its caller needs, read from the bytes alone (nothing is loaded).

The dynamic loader maps a library's segments from the file as its program headers
describe them; a segment that reaches past the end of a truncated file maps pages with
nothing behind them, and the first touch of one kills the process with SIGBUS, inside
``dlopen``, before Python can catch anything. A checksum proves only that the bytes are
those it was computed on (a checksum file written for a truncated library matches it),
so the extents are checked too. Symbols are read from the dynamic symbol table, so a
library that is not the one asked for is refused before its constructors run.
"""

from __future__ import annotations

import struct

_MAGIC = b"\x7fELF"
_PT_LOAD = 1
_SHT_NOBITS = 8  # a section that occupies no bytes of the file (.bss)
_SHT_DYNSYM = 11
_SHN_UNDEF = 0
_LAYOUTS = {
    # ELF class: the header's (phoff, shoff, phentsize, phnum, shentsize, shnum) fields;
    # a program header's (type, offset, filesz); a section header's (type, offset, size,
    # link, entsize); a symbol's (name, shndx) and size, as struct formats
    1: ("16x12xII6xHHHH", "II4x4xI", "4xI4x4xIII8xI", "I10xH", 16),
    2: ("16x16xQQ6xHHHH", "I4xQ8x8xQ", "4xI8x8xQQI12xQ", "I2xH", 24),
}


def _fields(data: bytes, fmt: str, offset: int) -> tuple:
    return struct.unpack_from(fmt, data, offset)


def _defined_symbols(data, sections, byte_order, symbol, size) -> set[str] | None:
    """The names the dynamic symbol table defines, or None when there is none."""
    for kind, offset, length, link, _ in sections:
        if kind != _SHT_DYNSYM or link >= len(sections):
            continue
        _, strings, strings_length, _, _ = sections[link]
        names = set()
        for start in range(offset, offset + length - size + 1, size):
            name, index = _fields(data, byte_order + symbol, start)
            if index != _SHN_UNDEF and name:
                end = data.find(b"\0", strings + name, strings + strings_length)
                if name >= strings_length or end < 0:
                    return set()  # names outside their table: none is defined
                names.add(data[strings + name : end].decode("ascii", "replace"))
        return names
    return None


def image_problem(data: bytes, symbols: tuple[str, ...] = ()) -> str | None:
    """Why ``data`` must not be handed to the dynamic loader, or None.

    Bytes that are not ELF are left to the loader (which refuses them with an error, not
    a crash); an ELF file must hold every byte its program and section headers name, and
    define each of ``symbols``.

    Parameters
    ----------
    data : bytes
        The library's content.
    symbols : tuple of str
        Names the library must define (its caller's entry points).

    Returns
    -------
    str or None
        The reason in words ("is cut short: ...", "lacks the symbols ..."), or None.
    """
    if not data.startswith(_MAGIC):
        return None
    layout = _LAYOUTS.get(data[4]) if len(data) > 6 else None
    if layout is None or data[5] not in (1, 2):
        return "has a malformed ELF header"
    header, program, section, symbol, symbol_size = layout
    byte_order = "<" if data[5] == 1 else ">"
    try:
        phoff, shoff, phentsize, phnum, shentsize, shnum = _fields(data, byte_order + header, 0)
        extents = [("program headers", phoff, phentsize * phnum)]
        extents += [("section headers", shoff, shentsize * shnum)]
        for i in range(phnum):
            kind, offset, length = _fields(data, byte_order + program, phoff + i * phentsize)
            if kind == _PT_LOAD:
                extents.append((f"segment {i}", offset, length))
        sections = [
            _fields(data, byte_order + section, shoff + i * shentsize) for i in range(shnum)
        ]
        extents += [
            (f"section {i}", s[1], s[2]) for i, s in enumerate(sections) if s[0] != _SHT_NOBITS
        ]
    except struct.error:  # a header table past the end
        return f"is cut short: its headers reach past its {len(data)} bytes"
    for what, offset, length in extents:
        if offset + length > len(data):
            return f"is cut short: its {what} ends at byte {offset + length} of {len(data)}"
    if not symbols:
        return None
    defined = _defined_symbols(data, sections, byte_order, symbol, symbol_size)
    missing = [name for name in symbols if defined is None or name not in defined]
    if missing:
        return f"lacks the symbols {', '.join(missing)} (not the library built for this key)"
    return None

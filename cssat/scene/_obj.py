"""The OBJ checks of :func:`cssat.scene.load_mesh`: a file cut or malformed in its face list is
refused (trimesh would load it without the faces it cannot parse)."""

from __future__ import annotations

from cssat._checks import FieldError


def check_obj(data: bytes, field: str, path: str) -> int:
    """Refuse an OBJ file that is cut or malformed in its face list, which trimesh would load
    without the faces it cannot parse: every ``f`` line needs at least three vertex references,
    each an integer within the vertices listed (negative: relative), and the file must not end in
    the middle of a line of data. Returns the triangles the ``f`` lines describe (fan
    triangulation), which the caller compares with those loaded."""
    lines = data.split(b"\n")
    n_vertices, expected = 0, 0
    for i, raw in enumerate(lines, 1):
        line = raw.split(b"#", 1)[0].strip()
        if line.startswith(b"v "):
            n_vertices += 1
        elif line.startswith(b"f ") or line == b"f":
            refs = line.split()[1:]
            try:
                idx = [int(r.split(b"/", 1)[0]) for r in refs]
            except ValueError:
                raise FieldError(field, f"{path!r} line {i}: a face with a vertex reference that is not an "
                                        f"integer: {raw[:60].decode(errors='replace')!r}") from None
            if len(idx) < 3:
                raise FieldError(field, f"{path!r} line {i}: a face needs at least 3 vertices, got {len(idx)} "
                                        "(the file may be cut mid-way)")
            bad = [k for k in idx if k == 0 or k > n_vertices or k < -n_vertices]
            if bad:
                raise FieldError(field, f"{path!r} line {i}: vertex reference {bad[0]} outside the "
                                        f"{n_vertices} vertices listed before it")
            expected += len(idx) - 2
    last = lines[-1].split(b"#", 1)[0].strip()
    if last[:2] in (b"v ", b"f ", b"vn", b"vt"):
        raise FieldError(field, f"{path!r} ends in the middle of a line ({last[:40].decode(errors='replace')!r}): "
                                "the file looks cut; end it with a newline if it is complete")
    return expected

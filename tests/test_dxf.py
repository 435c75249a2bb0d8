"""DXF curves to LINE/ARC chains (zwcore.io.dxf), read back through ezdxf.

The reference geometry is the input drawing itself, sampled by ezdxf (splines
flattened far below the tolerance); the output is read back by ezdxf and sampled
from its DXF attributes here.
"""

from __future__ import annotations

import io
import math

import ezdxf
import numpy as np
import pytest

from tests.nc_reader import densify, two_sided
from zwcore.errors import InvalidInputError, LimitExceededError
from zwcore.io.dxf import chains_to_dxf, dxf_to_chains

TOL = 0.01
STEP = 0.002


def drawing() -> bytes:
    doc = ezdxf.new("R2010")
    msp = doc.modelspace()
    t = np.linspace(0, 1.5 * math.pi, 300)
    msp.add_lwpolyline(np.c_[20 * np.cos(t), 20 * np.sin(t)].tolist(), dxfattribs={"layer": "C"})
    # bulges: a half circle (bulge 1) and a quarter arc (tan(pi/8)) between straight runs
    msp.add_lwpolyline([(0, 50, 0), (10, 50, 1.0), (20, 50, 0), (20, 60, math.tan(math.pi / 8)),
                        (30, 70, 0), (40, 70, 0)], format="xyb", dxfattribs={"layer": "B"})
    msp.add_spline([(0, -30), (10, -20), (20, -30), (30, -40), (40, -25)],
                   dxfattribs={"layer": "S"})
    p = msp.add_polyline2d([(60, 0), (80, 0), (80, 20), (60, 20)], dxfattribs={"layer": "P"})
    p.close(True)
    msp.add_line((0, 0), (5, 5), dxfattribs={"layer": "L"})
    msp.add_arc((100, 100), 3, 10, 100, dxfattribs={"layer": "A"})
    out = io.StringIO()
    doc.write(out)
    return out.getvalue().encode()


def entity_points(e: ezdxf.entities.DXFGraphic) -> np.ndarray:
    """Dense points of an input or output entity (ARC sampled from its attributes here)."""
    kind = e.dxftype()
    if kind == "LINE":
        return densify(np.array([e.dxf.start.vec2, e.dxf.end.vec2], dtype=float), STEP)
    if kind in ("ARC", "CIRCLE"):
        c, r = e.dxf.center, e.dxf.radius
        a0 = math.radians(e.dxf.start_angle) if kind == "ARC" else 0.0
        a1 = math.radians(e.dxf.end_angle) if kind == "ARC" else 2 * math.pi
        sweep = (a1 - a0) % (2 * math.pi) or 2 * math.pi
        n = math.ceil(sweep * r / STEP) + 1
        a = a0 + np.linspace(0, sweep, n)
        return np.c_[c[0] + r * np.cos(a), c[1] + r * np.sin(a)]
    # polylines with bulges and splines: ezdxf's own flattening, far below the tolerance
    from ezdxf import path

    pts = np.array([(v.x, v.y) for v in path.make_path(e).flattening(TOL / 100)])
    return densify(pts, STEP)


def by_layer(data: bytes | str) -> dict[str, np.ndarray]:
    doc = ezdxf.read(io.StringIO(data if isinstance(data, str) else data.decode()))
    out: dict[str, list[np.ndarray]] = {}
    for e in doc.modelspace():
        out.setdefault(e.dxf.layer, []).append(entity_points(e))
    return {k: np.vstack(v) for k, v in out.items()}


def test_round_trip_reads_back_within_tolerance() -> None:
    data = drawing()
    res = dxf_to_chains(data, TOL)
    assert res.counts == {"LWPOLYLINE": 2, "SPLINE": 1, "POLYLINE": 1, "LINE": 1, "ARC": 1}
    text = chains_to_dxf((c.layer, c.segments) for c in res.chains)
    back = ezdxf.read(io.StringIO(text))
    assert {e.dxftype() for e in back.modelspace()} <= {"LINE", "ARC", "CIRCLE"}
    want, got = by_layer(data), by_layer(text)
    assert set(got) == set(want)
    for layer in want:
        d_in, d_out = two_sided(want[layer], got[layer])
        assert d_in <= TOL + STEP and d_out <= TOL + STEP, layer
    # the bulges, the ARC and the 40 x 20 rectangle come back as exactly what they are
    arcs = [(e.dxf.layer, round(e.dxf.radius, 9)) for e in back.modelspace()
            if e.dxftype() == "ARC"]
    assert ("B", 5.0) in arcs and ("B", round(math.hypot(10, 10) / 2 / math.sin(math.pi / 4),
                                              9)) in arcs
    assert ("A", 3.0) in arcs
    rect = [e for e in back.modelspace() if e.dxf.layer == "P"]
    assert [e.dxftype() for e in rect] == ["LINE"] * 4
    circle = [e for e in back.modelspace() if e.dxf.layer == "C"]
    assert all(e.dxftype() == "LINE" or abs(e.dxf.radius - 20) <= 2 * TOL
               for e in circle if e.dxftype() == "ARC" and e.dxf.radius > 1)


def test_mirrored_ocs_polyline_is_read_in_world_coordinates() -> None:
    doc = ezdxf.new("R2010")
    msp = doc.modelspace()
    # extrusion -Z: OCS x is world -x, and the bulge turns the other way in the world
    msp.add_lwpolyline([(0, 0, 0), (10, 0, 1.0), (20, 0, 0)], format="xyb",
                       dxfattribs={"extrusion": (0, 0, -1)})
    out = io.StringIO()
    doc.write(out)
    res = dxf_to_chains(out.getvalue().encode(), TOL)
    segs = res.chains[0].segments
    assert segs[0].start == pytest.approx((0.0, 0.0)) and segs[0].end == pytest.approx((-10, 0))
    arc = segs[1]
    assert arc.center == pytest.approx((-15.0, 0.0)) and arc.radius == pytest.approx(5.0)
    # OCS ccw over (10..20, 0) bulges to OCS -y; mirrored in x it runs clockwise, still -y
    mid = (arc.center[0], arc.center[1] - 5.0)
    got = by_layer(chains_to_dxf([("0", segs)]))["0"]
    assert np.min(np.hypot(*(got - mid).T)) < 1e-3


@pytest.mark.parametrize(("data", "reason"), [
    (b"", "empty"),
    (b"this is not a drawing at all", "not a readable DXF"),
    (b"0\nSECTION\n2\nENTITIES\n0\nENDSEC\n0\nEOF\n", "no LWPOLYLINE"),
    (b"AutoCAD Binary DXF\r\n\x1a\x00junk", "binary"),
])
def test_bad_drawings(data: bytes, reason: str) -> None:
    with pytest.raises(InvalidInputError) as e:
        dxf_to_chains(data, TOL)
    assert e.value.field == "body" and reason in e.value.reason


def test_drawing_without_curves_and_work_bound() -> None:
    doc = ezdxf.new("R2010")
    doc.modelspace().add_line((0, 0), (1, 1))
    doc.modelspace().add_circle((0, 0), 2)
    out = io.StringIO()
    doc.write(out)
    with pytest.raises(InvalidInputError) as e:
        dxf_to_chains(out.getvalue().encode(), TOL)
    assert "1 CIRCLE, 1 LINE" in e.value.reason
    with pytest.raises(LimitExceededError) as e2:
        dxf_to_chains(drawing(), 1e-7, max_resolution=1e5)
    assert e2.value.field == "tolerance"

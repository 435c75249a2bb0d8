"""G-code programs and DXF drawings through the arc fitter: the ``/v1/arcs`` results.

The compute functions are module level with plain arguments: they run in a
worker process, fitting being Python-bound.
"""

from __future__ import annotations

from typing import Any

from zwcore.arcs.fit import Segment
from zwcore.io.dxf import chains_to_dxf, dxf_to_chains
from zwcore.io.gcode_program import rewrite_program

#: Request media types read as an NC program and as a DXF drawing.
GCODE_TYPES = ("text/plain", "text/x-gcode", "application/x-gcode")
DXF_TYPES = ("application/dxf", "image/vnd.dxf", "application/x-dxf", "image/x-dxf")
def input_key(task_id: str) -> str:
    """Store key beside a task's result holding its input, for previews to draw."""
    return f"{task_id}.input"


#: Response media type of the DXF when a client asks for the file itself.
DXF_MEDIA_TYPE = "application/dxf"


def sniff(raw: bytes) -> str:
    """The media type of an octet-stream upload: a DXF begins with group code 0 and
    ``SECTION`` (or a 999 comment); anything else is read as a program."""
    head = raw[:4096].split(b"\n", 4)
    first = [line.strip() for line in head[:2]]
    if (first and first[0] in (b"0", b"999")) or raw.startswith(b"AutoCAD Binary DXF"):
        return DXF_MEDIA_TYPE
    return GCODE_TYPES[0]


def segment_json(s: Segment) -> dict[str, Any]:
    out: dict[str, Any] = {"kind": s.kind, "start": list(s.start), "end": list(s.end)}
    if s.kind == "arc":
        out.update(center=list(s.center or ()), radius=s.radius, ccw=s.ccw, sweep=s.sweep)
    return out


def gcode_result(text: str, tolerance: float, corner_angle_deg: float,
                 max_radius: float | None, max_points: int, max_resolution: float
                 ) -> dict[str, Any]:
    """The rewritten program, its runs and figures."""
    prog = rewrite_program(text, tolerance, corner_angle_deg=corner_angle_deg,
                           max_radius=max_radius, max_points=max_points,
                           max_resolution=max_resolution)
    runs = [{"first_line": r.first_line, "last_line": r.last_line, "z": r.z,
             "moves_before": r.moves_before, "moves_after": r.moves_after,
             "rewritten": r.rewritten, "segments": [segment_json(s) for s in r.segments],
             "corners": list(r.corners), "max_deviation_points": r.max_deviation_points,
             "max_deviation_chain": r.max_deviation_chain} for r in prog.runs]
    return {"tolerance": tolerance, "program": prog.text, "summary": {
        "moves_before": prog.moves_before, "moves_after": prog.moves_after,
        "bytes_before": prog.bytes_before, "bytes_after": prog.bytes_after,
        "max_deviation": prog.max_deviation, "runs": len(prog.runs),
        "runs_rewritten": sum(r.rewritten for r in prog.runs),
        "unparsable_lines": len(prog.unparsable_lines),
        "unparsable_line_numbers": list(prog.unparsable_lines[:1000]),
        "decimals": prog.decimals}, "runs": runs, "notes": list(prog.notes)}


def dxf_result(data: bytes, tolerance: float, corner_angle_deg: float,
               max_points: int, max_resolution: float) -> dict[str, Any]:
    """The drawing's chains as JSON and as a DXF of LINE and ARC entities."""
    res = dxf_to_chains(data, tolerance, corner_angle_deg=corner_angle_deg,
                        max_points=max_points, max_resolution=max_resolution)
    segs = [s for c in res.chains for s in c.segments]
    n_arcs = sum(s.kind == "arc" for s in segs)
    chains = [{"source": c.source, "handle": c.handle, "layer": c.layer, "closed": c.closed,
               "fitted": c.fitted, "segments": [segment_json(s) for s in c.segments],
               "points": c.points.tolist(), "corners": list(c.corners),
               "max_deviation_points": c.max_deviation_points,
               "max_deviation_chain": c.max_deviation_chain} for c in res.chains]
    return {"tolerance": tolerance,
            "dxf": chains_to_dxf((c.layer, c.segments) for c in res.chains),
            "summary": {"entities": res.counts, "chains": len(res.chains),
                        "n_segments": len(segs), "n_arcs": n_arcs, "n_lines": len(segs) - n_arcs,
                        "max_deviation": res.max_deviation},
            "chains": chains, "notes": list(res.notes)}


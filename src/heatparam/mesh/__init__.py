"""The paper's mesh M: validation at the door, topology, planar helpers, seams.

``validate``  MeshInfo, validate_mesh — a connected, oriented 2-manifold with border (or any with ``flatten=False``)
``topology``  edges, boundary loops (one walker), loop lengths, vertex compaction, face areas
``planar``    signed areas, orientation, constrained Delaunay triangulation, shelf packing of boxes
``seams``     hole seams (shortest paths joining holes to the border) and cutting the mesh open
"""

from heatparam.mesh.planar import make_ccw, polygon_area, shelf_pack, signed_areas, triangulate
from heatparam.mesh.seams import cut_open, hole_seams
from heatparam.mesh.topology import (
    DEGENERATE_AREA_REL,
    Compaction,
    boundary_edges,
    boundary_loops,
    compact,
    edge_graph,
    face_areas,
    loop_length,
    loops_outer_first,
    unique_edges,
)
from heatparam.mesh.validate import NEARLY_CLOSED_RATIO, MeshInfo, validate_mesh

__all__ = [
    "DEGENERATE_AREA_REL", "NEARLY_CLOSED_RATIO", "Compaction", "MeshInfo", "boundary_edges", "boundary_loops",
    "compact", "cut_open", "edge_graph", "face_areas", "hole_seams", "loop_length", "loops_outer_first",
    "make_ccw", "polygon_area", "shelf_pack", "signed_areas", "triangulate", "unique_edges", "validate_mesh",
]

"""A frame of the cell as a meshio mesh: VTU for ParaView, STL of the
surface, Gmsh, and every other format meshio writes."""

import numpy as np


def frame_mesh(result, frame: int = -1):
    """meshio.Mesh of frame k: the vertex positions (m), the tetrahedra and
    their region (0 cytoplasm, 1 nucleus) as cell data."""
    import meshio

    if result.frame_count == 0 or len(result.tetrahedra) == 0:
        raise ValueError(f"{result.path}: no cell mesh in this result (scene {result.scene!r})")
    cell_data = {}
    if len(result.cell_region) == len(result.tetrahedra):
        cell_data["cell_region"] = [np.asarray(result.cell_region, dtype=np.int32)]
    return meshio.Mesh(points=result.positions(frame), cells=[("tetra", result.tetrahedra)], cell_data=cell_data)


def surface_triangles(tetrahedra: np.ndarray) -> np.ndarray:
    """The boundary faces of a tetrahedral mesh (each face of exactly one
    tetrahedron), oriented outward when the tetrahedra are positively oriented."""
    tets = np.asarray(tetrahedra, dtype=np.int64)
    # The faces opposite vertices 0..3, each ordered so that its normal points away from that vertex.
    faces = np.concatenate([tets[:, [1, 2, 3]], tets[:, [0, 3, 2]], tets[:, [0, 1, 3]], tets[:, [0, 2, 1]]])
    key = np.sort(faces, axis=1)
    _, index, counts = np.unique(key, axis=0, return_index=True, return_counts=True)
    return faces[index[counts == 1]]


def write_frame(result, path, frame: int = -1, file_format=None):
    """Writes frame k with meshio (format from the extension, or file_format).
    Formats of surfaces only (STL, OFF, PLY) get the boundary triangles."""
    import meshio

    mesh = frame_mesh(result, frame)
    name = str(path).lower()
    surface_only = (file_format or "").split("-")[0] in ("stl", "off", "ply") or name.endswith((".stl", ".off", ".ply"))
    if surface_only:
        mesh = meshio.Mesh(points=mesh.points, cells=[("triangle", surface_triangles(result.tetrahedra))])
    meshio.write(path, mesh, file_format=file_format)
    return path

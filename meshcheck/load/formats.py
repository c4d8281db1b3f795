"""The files meshcheck reads, by how their names end: a module without readers, so the command
line can sort its inputs before it imports them (trimesh, scipy, OpenCASCADE)."""

STEP_EXTENSIONS = (".step", ".stp")
URDF_EXTENSIONS = (".urdf",)
SUPPORTED_EXTENSIONS = (
    ".stl", ".obj", ".ply", ".off", ".glb", ".gltf", ".3mf", *STEP_EXTENSIONS, *URDF_EXTENSIONS
)  # fmt: skip

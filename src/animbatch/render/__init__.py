"""Off-screen rendering with PyVista/VTK (EGL or OSMesa). Everything that imports pyvista lives in this package."""

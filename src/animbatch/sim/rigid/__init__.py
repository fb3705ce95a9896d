"""Rigid-body geometry: shapes, mass properties, polyhedra (numbers only)."""

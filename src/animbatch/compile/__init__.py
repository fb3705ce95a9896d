"""The wall: scene spec -> Model, force terms, contacts, emitters and the geometry the renderer draws.

This is the only package that imports both :mod:`animbatch.scene` (the file format) and :mod:`animbatch.sim`
(the numbers). Checks that need geometry (mesh files, pin selections) live here too, since the scene layer
cannot build geometry.
"""

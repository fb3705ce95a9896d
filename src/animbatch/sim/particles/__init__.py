"""Particle systems: emitters that give birth to particles, a pool of slots they live and die in, and the one-way
simulation that moves them through the scene's fields and off its colliders.

Emitted particles are many, small and short-lived; they feel the scene but do not act on it (no particle pushes on a
body or on another particle, as in the lecture notes). So they are simulated *after* the scene's bodies, on their
own, following the bodies' trajectory where an emitter moves with a body (see :mod:`animbatch.sim.particles.simulate`).
"""

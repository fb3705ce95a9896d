"""Contact detection and response between rigid bodies, deformables and colliders (numbers only)."""

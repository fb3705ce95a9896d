"""Teaching: assignment templates to start from (:mod:`.templates`) and grading against a reference
(:mod:`.grade`)."""

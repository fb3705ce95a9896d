"""What the test modules share besides fixtures: scenes and their runs, closed forms, mutated scenes, paths.
Test modules import from here, never from each other or from conftest."""

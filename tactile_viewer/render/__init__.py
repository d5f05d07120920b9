"""Drawing with pyvista alone (no Qt): the 3-D scene of a frame and movies of a recording."""

"""The telerobot's world on contact physics (MuJoCo): the model built from the cell, the world that steps it."""

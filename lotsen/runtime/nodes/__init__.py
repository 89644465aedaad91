"""Runtime nodes: the glue between pure algorithms, the bus and the clock."""

"""The viewer's state in plain Python (no Qt): the model and its worker, solved frames, the time series."""

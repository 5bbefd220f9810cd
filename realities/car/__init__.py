"""Reality generator "car": a car on a track, four instrumented wheels (see README.md)."""

"""Animation: turning FAP streams, timelines and a model's habits into one parameter vector per
frame (see :mod:`vtts.animate.fapstream` for playing a FAP stream on a given model)."""

"""The render's stages, in the order they run (:mod:`.session` says what each does): the keys of the stats'
``seconds``, of the progress display and of the benchmarks' tables, numbered 1-6 in that order everywhere. A module of
their own, so that the session that runs them and the package that names them import it, not each other."""

STAGES = ("samples", "irradiance", "indirect", "transport", "screen", "shading")

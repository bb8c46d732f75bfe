"""What a person reads and sees: terminal text, the verdict against the theory, figures, videos.

:mod:`.terminal` (values with units, tables), :mod:`.verdict` (every run against the theory,
for the nightly's summary and the report), :mod:`.figures` (the sweep's and the atlas's, and
headless matplotlib) and :mod:`.video` (a video's timing and sizes). Nothing here starts a
run: :mod:`tippetop.compare.studies.render` runs a scene for a video. The HTML report is the
:mod:`tippetop.compare.report` room.
"""

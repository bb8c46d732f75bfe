"""What a person reads and sees: terminal text, the verdict against the theory, figures, videos.

:mod:`.terminal` (values with units, tables), :mod:`.verdict` (every run against the theory,
for the nightly's summary and the report), :mod:`.figures` (the sweep's and the atlas's, and
headless matplotlib) and :mod:`.video` (an MP4 of a run). The HTML report is the
:mod:`tippetop.compare.report` room.
"""

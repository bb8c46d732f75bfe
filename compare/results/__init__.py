"""Results: what a study returns, as frozen dataclasses with their fields.

Each result is built by its study (:mod:`tippetop.compare.studies`), printed by
:mod:`tippetop.compare.presentation` and drawn by the reports, and says itself as JSON
(``to_json``, the command's ``--json``) and reads itself back (``from_json``). This room sits
below the presentation and the studies, so that both can name a result's type.
"""

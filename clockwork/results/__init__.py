"""Results: what a run leaves behind.

``files``: atomic writing of JSON, CSV and bytes, and the output
directory's checks; ``cache``: finished sweep points shared by runs;
``plots`` and ``headlines``: registries filled per figure family;
``report``: a scene's summary.json, CSV files and plots; ``gallery``: the
gallery's index page.
"""

"""``strol-bench serve``: the study in a browser (server, sessions, page; the ``[serve]`` extra)."""

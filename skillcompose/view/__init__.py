"""``skillcompose view``: a local web viewer for runs, FSA files, replays and live FSAs.

The core (``skillcompose``) never imports this package. :mod:`.live` (publishing a running
FSA's state) and :mod:`.data` / :mod:`.episode` (what the pages show) load no web code;
:mod:`.app` builds the pages with NiceGUI, and :mod:`.cli` registers the subcommand.
"""

"""The shared leaderboard kept in the repository under ``leaderboard/``.

* :mod:`~frbench.leaderboard.results`: checks a results file against its schema and itself;
* :mod:`~frbench.leaderboard.scores`: recomputes scores and the track from cells;
* :mod:`~frbench.leaderboard.records`: record building, validation and atomic storage;
* :mod:`~frbench.leaderboard.render`: text table, JSON, ``README.md`` and ``index.html``;
* :mod:`~frbench.leaderboard.board`: ``submit``, ``regenerate`` and ``check``;
* :mod:`~frbench.leaderboard.paths`: where the leaderboard folder is.

The commands are ``frbench submit`` and ``frbench leaderboard`` (see
:mod:`frbench.commands.leaderboard`).
"""

from frbench.leaderboard.board import check, read_results, regenerate, submit
from frbench.leaderboard.results import check_results

__all__ = ["check", "check_results", "read_results", "regenerate", "submit"]

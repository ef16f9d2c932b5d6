"""The one error a bad world (or bad command-line input) raises."""

from __future__ import annotations


class WorldError(Exception):
    """A world file with problems; ``problems`` lists every one as ``path: message``."""

    def __init__(self, problems: list[str], source: str = "world"):
        self.problems = list(problems)
        self.source = source
        super().__init__(f"{source}: {len(problems)} problem(s)\n" + "\n".join(f"  {p}" for p in problems))

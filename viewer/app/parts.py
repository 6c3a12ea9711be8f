"""``Part``: an attribute of a class that holds parts with one job each (``Session``, ``App``)
which is one of its parts' own, read, called and set through the holder as on the part."""

from __future__ import annotations


class Part:
    """A holder's attribute that is one of its parts' (``holder.<part>.<name>``, by default
    the same name): read, called and set through the holder as on the part."""

    def __init__(self, part: str, name: str | None = None):
        self.part, self.name = part, name

    def __set_name__(self, owner, name):
        self.name = self.name or name

    def __get__(self, holder, owner=None):
        if holder is None:
            return self
        return getattr(getattr(holder, self.part), self.name)

    def __set__(self, holder, value):
        setattr(getattr(holder, self.part), self.name, value)

"""A registry of named things (parallax methods, placement strategies): what users extend with one
file and one line.  Items are kept in registration order under their ``name`` attribute; no global
state here: each registry is an instance owned by its module."""

from __future__ import annotations

from typing import Generic, Protocol, TypeVar


class Named(Protocol):
    """Anything with a ``name`` (str)."""

    @property
    def name(self) -> str: ...


T = TypeVar("T", bound=Named)

__all__ = ["NamedRegistry"]


class NamedRegistry(Generic[T]):
    """Items of one type by name.  ``kind`` is what an item is called in messages
    (e.g. ``"parallax method"``); ``item_type`` is the type :meth:`get` returns as is."""

    def __init__(self, kind: str, item_type: type[T]) -> None:
        self.kind = kind
        self.item_type = item_type
        self._items: dict[str, T] = {}

    def register(self, item: T, replace: bool = False) -> T:
        """Add ``item`` under its name (``replace``: allow overriding one of the same name); returns it."""
        if item.name in self._items and not replace:
            raise ValueError(f"{self.kind} {item.name!r} is already registered")
        self._items[item.name] = item
        return item

    def unregister(self, name: str) -> T:
        """Remove and return the item ``name`` (``ValueError`` when unknown)."""
        return self._items.pop(self.get(name).name)

    def get(self, item: str | T) -> T:
        """The registered item of that name (an item of ``item_type`` is returned as is;
        ``ValueError`` listing the known names)."""
        if isinstance(item, self.item_type):
            return item
        if item not in self._items:
            raise ValueError(f"unknown {self.kind} {item!r}; known: {', '.join(self._items)}")
        return self._items[item]

    def names(self) -> tuple[str, ...]:
        """Names of the registered items, in registration order."""
        return tuple(self._items)

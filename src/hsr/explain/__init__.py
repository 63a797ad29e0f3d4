"""Seeing why: explanation views (``explain``), ``hsr compare`` tables and montages, and the
self-contained HTML ``hsr report``."""

from .views import VIEWS, Explanation, explain

__all__ = ["VIEWS", "Explanation", "explain"]

"""The one caching idiom of lagrgen: a result computed once per object, held as long as the object.

`once_per(f)` makes `f(obj)` remember its result in a weak table keyed by `obj` (the frozen
description, its equations, ...), so a result lives exactly as long as what it was computed from.
`f.forget(obj)` drops one entry (a mutable owner that changed), `f.cache_clear()` all of them.
"""
import functools
import weakref


def once_per(function):
    """`function(obj)`, computed once per object `obj` (held weakly)."""
    results = weakref.WeakKeyDictionary()

    @functools.wraps(function)
    def cached(obj):
        try:
            return results[obj]
        except KeyError:
            value = results[obj] = function(obj)
            return value

    cached.forget = lambda obj: results.pop(obj, None)
    cached.cache_clear = results.clear
    return cached

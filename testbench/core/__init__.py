"""Core: messages, frames and geodesy, units, random streams, registry, errors.

Everything here is pure (no I/O) and imported by every other package.
"""

"""Thin command-line layers: parse arguments, call one library function, write files.

Each module defines ``register(subparsers)`` and sets ``handler`` on its parser via
``set_defaults(handler=...)``. Imports of NumPy/SciPy/meshes happen inside handlers.
"""

"""The live view: a running trial, a replayed demonstration or a saved trace as a rerun stream.

Needs the optional ``rerun-sdk`` package (``pip install 'multiform[view]'``); nothing else in
multiform imports this package, so the core runs without it.
"""

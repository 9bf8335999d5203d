"""Runs: configs and their resolution, the pipeline steps experiments compose, results
and their records (run folders, figures, videos, replay on native MuJoCo), many hosts.

The top layer of the library: it may import every other; nothing in the library imports it.
"""

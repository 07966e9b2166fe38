"""Data files shipped with hkpd (installed as ``hkpd.assets``); see README.md beside this file."""

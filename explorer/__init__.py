"""hkpd.explorer: the viser web app behind ``hkpd-explore`` (see the project issues for status).

It lives in the top-level ``explorer/`` folder and installs as ``hkpd.explorer``.
"""

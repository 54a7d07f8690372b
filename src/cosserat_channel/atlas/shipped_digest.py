"""The SHA-256 of the whole-plane atlas the package carries (data/whole_plane.nc), as
``make atlas`` wrote it, recorded by that same step (:func:`.store.record_shipped_digest`).
The file is used only when it matches (:func:`.store.shipped_problem`)."""

SHA256 = "d88144083bd8d64ff9279a2d5bc5784f85bb00081f1b327f7d11d9a467c5457c"

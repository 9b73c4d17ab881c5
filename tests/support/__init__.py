"""What the tests of every area share beside their fixtures: clusters and sweeps in
subprocesses, the store's fault points, forged files, the tests' catalogs, a kind from outside
the package, motion checks written independently of the kinematics stage, and where the
repository is."""

"""The geoproc command line (installed as the package ``geoproc_cli``)."""

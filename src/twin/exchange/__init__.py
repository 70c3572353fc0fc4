"""The tester system exchanged with other FMI tools: :mod:`twin.exchange.ssp` writes a
scenario's system as an SSP 1.0 archive (read back by :mod:`twin.config.ssp`)."""

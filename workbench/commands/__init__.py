"""One module per subcommand: argument handling and file I/O around the pure numerics."""

"""Command-line interface: parses options, builds configs, calls the library, prints."""

"""The teleprogramming language: statement models, parser, formatter and checks."""

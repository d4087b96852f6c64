"""The C runtimes under AddressSanitizer and UndefinedBehaviorSanitizer (test_sanitizers.py runs the rest)."""

"""The sequential chain: the compiled loops on one core (`loops`), one template for every rule and selector,
within the limits of `engine.harness`."""

"""The case file: its schema (every option, its choices and default), loading YAML into a typed
case, the checks that refuse impossible cases, and assembling a case into model, data and NLP."""

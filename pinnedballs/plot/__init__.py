"""Pictures: state pictures in each geometry's view (`states`), figures of observables (`figures`),
the figures of one run (`run`) and movies of its snapshots (`animation`); `base` holds what they share."""

"""Pictures: state pictures in each geometry's view (`states`), figures of observables (`figures`),
the figures of one run (`run`), movies of its snapshots (`animation`) and how objects show themselves in
a notebook (`display`, which hands a geometry and a simulation their pictures); `base` holds what they share."""

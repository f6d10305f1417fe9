"""Exact counts: the chain in the number field of the contact normals, on the same picks as the float chain.

``arithmetic="exact"`` runs it exactly, ``"certified"`` with rounding and every decision proved equal to
exact arithmetic's. `arithmetic` chooses the chain and checks the precision; `numbers` is the number fields
Q(sqrt d1, sqrt d2, ...) and their elements (`numbers.FieldNumber`); `chain` what every such chain shares
(`chain.FieldChain`); `rational` the chain in rationals (`rational.RationalChain`: any masses, restitution,
HCP's two roots); `fixed` the chain in fixed point (`fixed.FixedChain`: exact or certified at about the
cost of floats), its compiled loop `fixed_kernels`, its integers `limbs` and the state it resumes from
`fixed_state`."""

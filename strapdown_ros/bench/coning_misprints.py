"""
The misprints of Aksyonenko 2014 (003) in its coning algorithms and coning model.

Fixed text for the ``coning_bench`` report: the printed formula, the corrected one and why,
per thesis equation; the full algebra is in doc/coning_derivations.md.  The measured
evidence beside each is filled in from the run by ``coning_report``.
"""

#: (algorithm, thesis equations, printed formula, corrected formula, derivation)
MISPRINTS = [
    (
        '3',
        '(1.78), (2.16)',
        'φ = q3 + q2 + q1 + 9/8 (q3 × q1)',
        'φ = q1 + q2 + q3 + 9/8 (q1 × q3)',
        (
            'Order 4 needs Σ_m m·K_m = N³/12 = 27/12 with the later increment on the right; the'
            ' only pair (spacing 2) gives K_2 = 9/8. The printed operand order gives K_2 = −9/8:'
            ' the correction adds to the uncorrected drift instead of cancelling it.'
        ),
    ),
    (
        '3.1',
        '(1.79), (2.17)',
        'φ = Σq + 9/20 (q3 − q1) × (q1 + 3/2 q2)',
        'φ = Σq + 9/20 (q1 + 3/2 q2) × (q3 − q1)',
        (
            "Expanded, the corrected form is 9/20 q1×q3 + 27/40 (q1×q2 + q2×q3): Miller's optimal"
            ' 3-sample algorithm, which meets both moment conditions (order 6). The printed form'
            ' is its exact negative.'
        ),
    ),
    (
        '4+',
        '(1.81), (2.19)',
        'φ = q2 + q2 + q3 + q3 + 4/3 [q1×q3 + q2×q3 + q2×q4]',
        'φ = Σq + 32/45 (q1×q2 + q3×q4) + 22/45 (q1 + q2) × (q3 + q4)',
        (
            'The printed sum is not Σq (the rotation is wrong even without coning) and Σ m·K_m ='
            " 20/3 ≠ 16/3. §1.4.4 derives 4+ by Runge's rule; Richardson extrapolation (16·φ_fine"
            ' − φ_coarse)/15, with φ_fine two 2-sample updates composed to second order and'
            ' φ_coarse algorithm 4, gives the form on the right: both moment conditions hold,'
            ' order 6 (a 5th order, as claimed, cannot occur: the coning drift is even in Ωh).'
            ' `4+_printed_terms` keeps the printed cross-product set with coefficients 22/15,'
            ' −8/15 solved from the same conditions (also order 6 by those conditions).'
        ),
    ),
    (
        '5',
        '(1.82), (2.20)',
        'φ = Σq − 1375/432 q4×q2 − 1625/864 q5×q1 + 875/216 (q4×q1 + q5×q2)',
        'φ = Σq − 1375/432 q2×q4 − 1625/864 q1×q5 + 875/216 (q1×q4 + q2×q5)',
        (
            'Every product has the later increment on the left: Σ m·K_m = −125/12 instead of'
            ' +125/12. With the operands in time order the first two moment conditions hold: order'
            ' 6 (claimed 4).'
        ),
    ),
    (
        '7',
        '(1.84), (2.22)',
        'φ3 = q1 + 1/6 (q2 × q1) − 1/24 (q3 × q1)',
        'φ = q3 + 1/6 (q2 × q3) − 1/24 (q1 × q3)   (q3 current)',
        (
            "With the thesis's own index convention of (1.83) (q1 oldest) the formula integrates"
            ' the oldest interval and its corrections have the wrong sign (`7_as_printed`, order'
            ' 2). Read with newest-first indices, the only causal reading, K_1 = 1/6, K_2 = −1/24'
            ' meet the order-4 condition (1/6 − 2/24 = 1/12) but not the order-6 one; the leading'
            ' coefficient is −1/40 against 1/60 for algorithm 6.'
        ),
    ),
]

#: (equation, printed, corrected, key of the measured evidence in ``model_checks``)
MODEL_MISPRINTS = [
    ('(2.6) U12', '−½(1 − cos α) sin 2νt', '+½(1 − cos α) sin 2νt', 'u12_printed_max_error'),
    (
        '(2.6) U22',
        'cos α + (1 − cos α) sin² νt',
        'cos α + (1 − cos α) cos² νt',
        'u22_printed_max_error',
    ),
    ('(2.7) Ω row 3', '[ω_y, ω_x, 0]', '[−ω_y, ω_x, 0]', 'omega_27_row3_sign_error'),
    (
        '(2.10) q_x, q_y',
        '−sin α (sin νt_k − sin ν(t_k − τ)), −sin α (cos νt_k − cos ν(t_k − τ))',
        'sin α (sin νt_k − sin νt_{k−1}), sin α (cos νt_k − cos νt_{k−1})',
        'increments_210_printed_max_error',
    ),
]

; Arithmetic right shift of a signed 32-bit word, truncating (floor) or rounding half up.
;   in:  ACC3..ACC0 = x (signed), ARG0 = s (0..31)
;   out: ACC3..ACC0 = x >> s (floor) or (x + 2^(s-1)) >> s (half up, ties towards +inf)
;   clobbers: COUNT, W, STATUS
;   Rounding uses (x + 2^(s-1)) >> s = ((x >> (s-1)) + 1) >> 1: s - 1 plain shifts, an increment, and a
;   last shift that brings in the true 33rd bit of the sum (so 2^31 - 1 rounds without overflow).

; ashr_n: ACC >>= COUNT (arithmetic; COUNT = 0 shifts nothing). 5 cycles a bit plus the loop's 3.
ashr_n:
        movf    COUNT, F
        btfsc   STATUS, Z
        return
an_bit:
        rlf     ACC3, W         ; C = sign bit
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        decfsz  COUNT, F
        goto    an_bit
        return

shr32:
        movf    ARG0, W
        movwf   COUNT
        goto    ashr_n          ; tail call

shr32r:
        movf    ARG0, W
        btfsc   STATUS, Z
        return                  ; s = 0: x
        movwf   COUNT
        decf    COUNT, F
        call    ashr_n          ; y = x >> (s - 1)
        bcf     STATUS, C       ; C = sign of y ...
        btfsc   ACC3, 7
        bsf     STATUS, C
        incf    ACC0, F         ; y + 1 (INCF leaves C alone)
        btfsc   STATUS, Z
        incf    ACC1, F
        btfsc   STATUS, Z
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
        btfss   ACC3, 7         ; ... and of y + 1: both negative <=> the 33-bit sum is negative
        bcf     STATUS, C
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        return

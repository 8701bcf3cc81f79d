; 16 x 16 -> 32-bit multiply, unsigned and signed (two's complement).
;   in:  ACC1:ACC0 = a, ARG1:ARG0 = b
;   out: ACC3:ACC2:ACC1:ACC0 = a * b (exact); ARG unchanged
;   clobbers: COUNT, TMP0, TMP1 (signed only), W, STATUS

; mul16u: shift-add, one multiplier bit per round. The 32-bit product ACC3:ACC2:ACC1:ACC0 starts as
; 0:0:a; each round adds b to the high half when the low bit is 1, then shifts the whole product right
; (the add's carry enters at the top), so after 16 rounds the multiplier has been shifted out.
mul16u:
        clrf    ACC2
        clrf    ACC3
        movlw   .16
        movwf   COUNT
mu_round:
        bcf     STATUS, C
        btfss   ACC0, 0
        goto    mu_shift
        movf    ARG0, W         ; high half += b (17-bit result, carry in C)
        addwf   ACC2, F
        movf    ARG1, W
        btfsc   STATUS, C
        incfsz  ARG1, W         ; ARG1 + carry; 0x100 leaves ACC3 as is and C set, as it should
        addwf   ACC3, F
mu_shift:
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        decfsz  COUNT, F
        goto    mu_round
        return

; mul16s: the unsigned product of the two bit patterns, corrected: a negative a contributed
; (a + 2^16) * b, so subtract b * 2^16; likewise for b. Modulo 2^32 the result is the signed product.
mul16s:
        movf    ACC0, W         ; keep a for the correction
        movwf   TMP0
        movf    ACC1, W
        movwf   TMP1
        call    mul16u
        btfss   TMP1, 7
        goto    ms_b
        movf    ARG0, W         ; a < 0: high half -= b
        subwf   ACC2, F
        movf    ARG1, W
        btfss   STATUS, C
        incfsz  ARG1, W
        subwf   ACC3, F
ms_b:
        btfss   ARG1, 7
        return
        movf    TMP0, W         ; b < 0: high half -= a
        subwf   ACC2, F
        movf    TMP1, W
        btfss   STATUS, C
        incfsz  TMP1, W
        subwf   ACC3, F
        return

; 32 / 16-bit divide: unsigned and signed, quotient truncated or rounded to nearest.
;   in:  ACC3:ACC2:ACC1:ACC0 = n (dividend), ARG1:ARG0 = d (divisor)
;   out: ACC3..ACC0 = quotient (32 bits); truncating divides also REM1:REM0 = remainder
;        (signed: the dividend's sign, n = q d + r, |r| < |d|)
;   d = 0: quotient = the word's maximum (n >= 0) or minimum (n < 0), remainder = n clipped to 16 bits,
;        FLAGS bits FLAG_DIV0 and FLAG_SAT set. Signed -2^31 / -1 saturates to 2^31 - 1 (FLAG_SAT), r = 0.
;   clobbers: ARG (signed: replaced by |d|), COUNT, SIGNS, TMP0, TMP1, REM, W, STATUS
;   Rounding: q = sign * ((|n| + |d| / 2) / |d|), ties away from zero; the 33-bit sum of the unsigned
;   divide enters the loop as its first remainder bit.

; udiv_core: restoring division of REM1:REM0:ACC (REM < ARG on entry) by ARG1:ARG0; 32 rounds, each
; shifts one dividend bit into the remainder and one quotient bit into ACC0.
udiv_core:
        movlw   .32
        movwf   COUNT
ud_round:
        bcf     STATUS, C
        rlf     ACC0, F
        rlf     ACC1, F
        rlf     ACC2, F
        rlf     ACC3, F
        rlf     REM0, F
        rlf     REM1, F
        btfsc   STATUS, C       ; 17-bit remainder: larger than any divisor
        goto    ud_sub
        movf    ARG1, W         ; compare REM with ARG, high byte first
        subwf   REM1, W
        btfss   STATUS, Z
        goto    ud_cmp
        movf    ARG0, W
        subwf   REM0, W
ud_cmp:
        btfss   STATUS, C       ; C = 1: REM >= ARG
        goto    ud_next
ud_sub:
        movf    ARG0, W         ; REM -= ARG (16 bits; the 17th cancels)
        subwf   REM0, F
        movf    ARG1, W
        btfss   STATUS, C
        incfsz  ARG1, W
        subwf   REM1, F
        bsf     ACC0, 0         ; quotient bit
ud_next:
        decfsz  COUNT, F
        goto    ud_round
        return

; div_by_zero: ARG = 0. Sets the flags; W = 0 for a non-negative n (the caller picks the quotient).
div_by_zero:
        bsf     FLAGS, FLAG_DIV0
        bsf     FLAGS, FLAG_SAT
        return

div32u:
        movf    ARG0, W
        iorwf   ARG1, W
        btfsc   STATUS, Z
        goto    du_zero
        clrf    REM0
        clrf    REM1
        goto    udiv_core       ; tail call
du_zero:
        call    div_by_zero
        movf    ACC0, W         ; remainder = min(n, 65535)
        movwf   REM0
        movf    ACC1, W
        movwf   REM1
        movf    ACC2, W
        iorwf   ACC3, W
        btfsc   STATUS, Z
        goto    set_umax
        movlw   0xFF
        movwf   REM0
        movwf   REM1
set_umax:                       ; ACC = 2^32 - 1
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movwf   ACC2
        movwf   ACC3
        return

divr32u:
        movf    ARG0, W
        iorwf   ARG1, W
        btfsc   STATUS, Z
        goto    dru_zero
        clrf    REM0
        clrf    REM1
        call    add_half_d      ; ACC += d / 2, the carry (33rd bit) in REM0
        goto    udiv_core
dru_zero:
        call    div_by_zero
        goto    set_umax

; add_half_d: ACC += ARG >> 1 (32 bits); a carry out of ACC3 sets REM0 to 1.
add_half_d:
        bcf     STATUS, C
        rrf     ARG1, W
        movwf   TMP1
        rrf     ARG0, W
        movwf   TMP0
        addwf   ACC0, F
        movf    TMP1, W
        btfsc   STATUS, C
        incfsz  TMP1, W
        addwf   ACC1, F
        btfss   STATUS, C
        return
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
        btfsc   STATUS, Z
        incf    REM0, F
        return

; signed_operands: |n| in ACC, |d| in ARG, SIGNS = quotient and dividend signs, REM = 0.
signed_operands:
        clrf    SIGNS
        clrf    REM0
        clrf    REM1
        btfss   ACC3, 7
        goto    so_d
        call    neg_acc
        movlw   3               ; dividend negative: quotient and remainder negative (so far)
        movwf   SIGNS
so_d:
        btfss   ARG1, 7
        return
        comf    ARG0, F         ; ARG = -ARG (|-32768| = 0x8000 fits the unsigned divisor)
        comf    ARG1, F
        incf    ARG0, F
        btfsc   STATUS, Z
        incf    ARG1, F
        movlw   1
        xorwf   SIGNS, F
        return

; signed_result: apply the quotient's sign; a positive quotient of 2^31 saturates to 2^31 - 1.
signed_result:
        btfss   SIGNS, 0
        goto    sr_pos
        goto    neg_acc         ; tail call
sr_pos:
        btfss   ACC3, 7
        return
        bsf     FLAGS, FLAG_SAT
set_smax:                       ; ACC = 2^31 - 1
        movlw   0xFF
        movwf   ACC0
        movwf   ACC1
        movwf   ACC2
        movlw   0x7F
        movwf   ACC3
        return

div32s:
        movf    ARG0, W
        iorwf   ARG1, W
        btfsc   STATUS, Z
        goto    ds_zero
        call    signed_operands
        call    udiv_core
        btfss   SIGNS, 1        ; remainder takes the dividend's sign
        goto    signed_result
        comf    REM0, F
        comf    REM1, F
        incf    REM0, F
        btfsc   STATUS, Z
        incf    REM1, F
        goto    signed_result
ds_zero:
        call    div_by_zero
        movf    ACC3, W         ; keep n's sign, then REM = n clipped to 16 bits
        movwf   SIGNS
        call    sat16
        movf    ACC0, W
        movwf   REM0
        movf    ACC1, W
        movwf   REM1
        btfss   SIGNS, 7
        goto    set_smax
set_smin:                       ; ACC = -2^31
        clrf    ACC0
        clrf    ACC1
        clrf    ACC2
        movlw   0x80
        movwf   ACC3
        return

divr32s:
        movf    ARG0, W
        iorwf   ARG1, W
        btfsc   STATUS, Z
        goto    drs_zero
        call    signed_operands
        call    add_half_d      ; |n| + |d|/2 < 2^32: no 33rd bit
        call    udiv_core
        goto    signed_result
drs_zero:
        call    div_by_zero
        btfss   ACC3, 7
        goto    set_smax
        goto    set_smin

; neg_acc: ACC = -ACC (32-bit two's complement).
neg_acc:
        comf    ACC0, F
        comf    ACC1, F
        comf    ACC2, F
        comf    ACC3, F
        incf    ACC0, F
        btfsc   STATUS, Z
        incf    ACC1, F
        btfsc   STATUS, Z
        incf    ACC2, F
        btfsc   STATUS, Z
        incf    ACC3, F
        return

; Routines of steps 4-5 in program memory page 1 (0x0800-0x0FFF): page 0 is full. They call nothing and
; jump only within themselves; page 0 calls them with CALL_P1 (PCLATH bit 3 set around the CALL; the
; interrupt saves and restores PCLATH).

; add16s: ACC1:ACC0 += ARG1:ARG0, saturated to 16 bits (FLAG_SAT when clipped)
add16s:
        movf    ACC1, W
        xorwf   ARG1, W
        movwf   TMP2                    ; bit 7: the signs differ (no overflow possible)
        movf    ARG0, W
        addwf   ACC0, F
        movf    ARG1, W
        btfsc   STATUS, C
        incfsz  ARG1, W
        addwf   ACC1, F
        btfsc   TMP2, 7
        return
        movf    ACC1, W                 ; same signs: overflow when the sum's sign differs
        xorwf   ARG1, W
        andlw   0x80
        btfsc   STATUS, Z
        return
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF
        movwf   ACC0
        movlw   0x7F
        movwf   ACC1
        btfss   ARG1, 7
        return
        clrf    ACC0
        movlw   0x80
        movwf   ACC1
        return

; select: W = the k-th smallest (k = W, from 0) of DURS[0 .. N_DUR - 1]: the d_i with
; #(d_j < d_i) <= k < #(d_j <= d_i) (no sorted copy: N_DUR^2 compares)
select:
        movwf   SEL_K
        clrf    TAP
sel_i:
        clrf    SEL_LT
        clrf    SEL_LE
        clrf    SEL_J
sel_j:
        movf    SEL_J, W
        addlw   DURS
        movwf   FSR
        movf    INDF, W
        movwf   TMP2                    ; d_j
        movf    TAP, W
        addlw   DURS
        movwf   FSR
        movf    INDF, W                 ; d_i
        subwf   TMP2, W                 ; d_j - d_i
        btfss   STATUS, C
        goto    sel_less
        btfsc   STATUS, Z
        incf    SEL_LE, F
        goto    sel_next
sel_less:
        incf    SEL_LT, F
        incf    SEL_LE, F
sel_next:
        incf    SEL_J, F
        LDB     N_DUR
        xorwf   SEL_J, W
        btfss   STATUS, Z
        goto    sel_j
        movf    SEL_LT, W               ; lt <= k
        subwf   SEL_K, W
        btfss   STATUS, C
        goto    sel_no
        movf    SEL_LE, W               ; k < le
        subwf   SEL_K, W
        btfsc   STATUS, C
        goto    sel_no
        movf    TAP, W
        addlw   DURS
        movwf   FSR
        movf    INDF, W
        return
sel_no:
        incf    TAP, F
        goto    sel_i


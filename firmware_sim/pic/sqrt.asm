; Integer square root of an unsigned 32-bit word: restoring shift-subtract, one root bit per round.
;   in:  ACC3..ACC0 = x (unsigned)
;   out: isqrt32:  ACC1:ACC0 = floor(sqrt(x)), ACC3:ACC2 = 0
;        isqrt32n: ACC2:ACC1:ACC0 = nearest integer: floor + 1 when x - r^2 > r (65536 for x >= 65535.5^2)
;        iroot4:   ACC0 = floor(x^(1/4)) = isqrt32(isqrt32(x)), ACC3..ACC1 = 0
;        REM2:REM1:REM0 = x - r^2 (isqrt32, isqrt32n before rounding)
;   clobbers: ARG (the root), COUNT, TMP0..TMP2, REM, W, STATUS
;   Each round: REM = 4 REM + the next two bits of x; trial = 4 root + 1; root = 2 root;
;   if REM >= trial: REM -= trial, root += 1. REM stays below 2^18, the trial below 2^18.
isqrt32:
        clrf    ARG0
        clrf    ARG1
        clrf    REM0
        clrf    REM1
        clrf    REM2
        movlw   .16
        movwf   COUNT
sq_round:
        call    sq_shift2       ; REM:ACC <<= 1, twice
        call    sq_shift2
        movf    ARG0, W         ; trial = 4 root + 1 in TMP2:TMP1:TMP0
        movwf   TMP0
        movf    ARG1, W
        movwf   TMP1
        clrf    TMP2
        bcf     STATUS, C
        rlf     TMP0, F         ; 2 root
        rlf     TMP1, F
        rlf     TMP2, F         ; leaves C = 0 (TMP2 was 0)
        rlf     TMP0, F         ; 4 root
        rlf     TMP1, F
        rlf     TMP2, F
        bsf     TMP0, 0         ; 4 root + 1
        bcf     STATUS, C       ; root = 2 root
        rlf     ARG0, F
        rlf     ARG1, F
        movf    TMP0, W         ; REM -= trial (24 bits)
        subwf   REM0, F
        movf    TMP1, W
        btfss   STATUS, C
        incfsz  TMP1, W
        subwf   REM1, F
        movf    TMP2, W
        btfss   STATUS, C
        incfsz  TMP2, W
        subwf   REM2, F
        btfss   STATUS, C
        goto    sq_restore
        bsf     ARG0, 0         ; REM >= trial: root bit 1
        goto    sq_next
sq_restore:
        movf    TMP0, W         ; REM < trial: REM += trial
        addwf   REM0, F
        movf    TMP1, W
        btfsc   STATUS, C
        incfsz  TMP1, W
        addwf   REM1, F
        movf    TMP2, W
        btfsc   STATUS, C
        incfsz  TMP2, W
        addwf   REM2, F
sq_next:
        decfsz  COUNT, F
        goto    sq_round
        movf    ARG0, W
        movwf   ACC0
        movf    ARG1, W
        movwf   ACC1
        clrf    ACC2
        clrf    ACC3
        return

sq_shift2:                      ; REM2:REM1:REM0:ACC3..ACC0 <<= 1 (a zero enters ACC0)
        bcf     STATUS, C
        rlf     ACC0, F
        rlf     ACC1, F
        rlf     ACC2, F
        rlf     ACC3, F
        rlf     REM0, F
        rlf     REM1, F
        rlf     REM2, F
        return

isqrt32n:
        call    isqrt32
        movf    REM2, F         ; REM > root? (REM >= 2^16 always is)
        btfss   STATUS, Z
        goto    sqn_up
        movf    REM0, W         ; root - REM: a borrow means REM > root
        subwf   ACC0, W
        movf    REM1, W
        btfss   STATUS, C
        incfsz  REM1, W
        subwf   ACC1, W
        btfsc   STATUS, C
        return
sqn_up:
        incf    ACC0, F
        btfsc   STATUS, Z
        incf    ACC1, F
        btfsc   STATUS, Z
        incf    ACC2, F
        return

iroot4:
        call    isqrt32
        goto    isqrt32         ; tail call

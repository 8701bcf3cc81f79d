; Saturate a signed 32-bit word to 16 bits.
;   in:  ACC3..ACC0 = x (signed)
;   out: ACC1:ACC0 = x clipped to -32768 .. 32767 (ACC3:ACC2 unchanged); FLAG_SAT set when clipped
;   clobbers: W, STATUS
;   x fits when ACC3 and ACC2 both equal the sign extension of ACC1 (0x00 or 0xFF).
sat16:
        movf    ACC2, W
        btfsc   ACC1, 7
        comf    ACC2, W         ; W = 0 when ACC2 is the extension of ACC1's sign
        btfss   STATUS, Z
        goto    s16_clip
        movf    ACC3, W
        btfsc   ACC1, 7
        comf    ACC3, W
        btfsc   STATUS, Z
        return                  ; fits
s16_clip:
        bsf     FLAGS, FLAG_SAT
        movlw   0xFF            ; x > 0: 0x7FFF
        movwf   ACC0
        movlw   0x7F
        movwf   ACC1
        btfss   ACC3, 7
        return
        clrf    ACC0            ; x < 0: 0x8000
        movlw   0x80
        movwf   ACC1
        return

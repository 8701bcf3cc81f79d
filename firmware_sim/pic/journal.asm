; journal_write: header version 3's page-commit journal entry (PROTOCOL.md section 2.7, protocol/journal_ring.py
; entry_bytes and ring_address), written to the journal ring of the step EEPROM over the MSSP (I2C master).
;
; Self-contained: not yet called from logger.asm's sample path (whose RAM map is being changed elsewhere); the
; bench journal_bench.asm runs it in gpsim (firmware_sim/pic/gpsim_journal.py). The includer sets JE_RAM, the
; first of 16 bank-0 bytes (or bank 1: they are read through FSR with IRP = 0) holding the entry's inputs:
;   JE_M+0..3   commit m, u32 LE (a multiple of 2: the run's page commits so far)
;   JE_S+0..3   the run's step records, u32 LE (the entry saturates it to 0xFFFF)
;   JE_R+0..3   recording_number, u32 LE
;   JE_N+0..3   recording_nonce, u32 LE
; It writes, as one page write at the start of ring page p = (recording_number + m / 2 - 1) mod 96 (byte
; 0xD000 + 128 p of the step EEPROM's block 0, control byte 0xA0), the 16 bytes m (4, LE), steps (2, LE,
; saturated), recording_number (4, LE), recording_nonce (4, LE), CRC-16/XMODEM of those 14 (2, big-endian),
; streaming the CRC as the bytes go out (no RAM buffer), then polls for the acknowledge until the EEPROM's
; write cycle is over (as scr_write does). x mod 96 takes no division: x = 32 y + (x mod 32), and y mod 3 is
; the sum of y's bytes mod 3 (256 = 1 mod 3), then of its nibbles (16 = 1 mod 3).
; Uses the kernels' common RAM as scratch: ACC0-3, TMP0-2, COUNT, REM0-1 (CRC), REM2. Stack: 3 levels with its
; own return (journal_write -> jr_bytes -> jr_byte, which jumps on to jr_tx). Returns in bank 0.
JE_M            equ     JE_RAM
JE_S            equ     JE_RAM + 4
JE_R            equ     JE_RAM + 8
JE_N            equ     JE_RAM + .12
JR_CONTROL      equ     0xA0            ; the step EEPROM's block 0, write (1010 B0 A1 A0 R/W)
JR_RING_HIGH    equ     0xD0            ; protocol/journal_ring.py RING_FIRST_BYTE = 0xD000
JR_RING_PAGES   equ     .96
JR_CRC_H        equ     REM1
JR_CRC_L        equ     REM0
JR_X            equ     REM2

journal_write:
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        bcf     STATUS, IRP
        movlw   JE_R                    ; TMP2 = recording_number mod 96
        call    jr_load
        call    jr_mod96
        movwf   TMP2
        movlw   JE_M                    ; + (m >> 1) mod 96
        call    jr_load
        bcf     STATUS, C
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        call    jr_mod96
        addwf   TMP2, F                 ; <= 190
        movlw   JR_RING_PAGES
        subwf   TMP2, W
        btfsc   STATUS, C
        movwf   TMP2                    ; < 96
        movlw   1                       ; - 1, mod 96
        subwf   TMP2, F
        movlw   JR_RING_PAGES
        btfss   STATUS, C
        addwf   TMP2, F
        bcf     STATUS, C
        rrf     TMP2, F                 ; TMP2 = p >> 1, C = p & 1
        clrf    TMP1
        rrf     TMP1, F                 ; TMP1 = the address's low byte, 128 (p & 1)
        movlw   JR_RING_HIGH
        addwf   TMP2, F                 ; TMP2 = its high byte
        I2C_CMD SEN
        movlw   JR_CONTROL
        call    jr_tx
        movf    TMP2, W
        call    jr_tx
        movf    TMP1, W
        call    jr_tx
        clrf    JR_CRC_H
        clrf    JR_CRC_L
        movlw   JE_M                    ; commit
        movwf   FSR
        movlw   4
        call    jr_bytes
        movf    JE_S + 2, W             ; steps, saturated to 16 bits
        iorwf   JE_S + 3, W
        btfss   STATUS, Z
        goto    jw_saturated
        movf    JE_S, W
        call    jr_byte
        movf    JE_S + 1, W
        call    jr_byte
        goto    jw_run
jw_saturated:
        movlw   0xFF
        call    jr_byte
        movlw   0xFF
        call    jr_byte
jw_run:
        movlw   JE_R                    ; recording_number, recording_nonce
        movwf   FSR
        movlw   8
        call    jr_bytes
        movf    JR_CRC_H, W             ; the CRC, big-endian
        call    jr_tx
        movf    JR_CRC_L, W
        call    jr_tx
        I2C_CMD PEN
jw_poll:                                ; acknowledge polling: the write cycle is over when the control byte is acknowledged
        I2C_CMD SEN
        movlw   JR_CONTROL
        call    jr_tx
        bsf     STATUS, RP0
        btfss   SSPCON2, ACKSTAT
        goto    jw_done
        I2C_CMD PEN
        goto    jw_poll
jw_done:
        I2C_CMD PEN
        return

; jr_load: ACC0-3 = the 4 bytes at W (bank 0/1, IRP = 0)
jr_load:
        movwf   FSR
        movf    INDF, W
        movwf   ACC0
        incf    FSR, F
        movf    INDF, W
        movwf   ACC1
        incf    FSR, F
        movf    INDF, W
        movwf   ACC2
        incf    FSR, F
        movf    INDF, W
        movwf   ACC3
        return

; jr_mod96: W = ACC3:ACC0 mod 96 (ACC destroyed; TMP0, COUNT)
jr_mod96:
        movf    ACC0, W
        andlw   0x1F
        movwf   TMP0                    ; x mod 32
        movlw   5
        movwf   COUNT
jm_shift:                               ; ACC = y = x >> 5
        bcf     STATUS, C
        rrf     ACC3, F
        rrf     ACC2, F
        rrf     ACC1, F
        rrf     ACC0, F
        decfsz  COUNT, F
        goto    jm_shift
        movf    ACC1, W                 ; ACC0 = y's bytes summed, the carries added back (256 = 1 mod 3)
        addwf   ACC0, F
        btfsc   STATUS, C
        incf    ACC0, F
        movf    ACC2, W
        addwf   ACC0, F
        btfsc   STATUS, C
        incf    ACC0, F
        movf    ACC3, W
        addwf   ACC0, F
        btfsc   STATUS, C
        incf    ACC0, F
        swapf   ACC0, W                 ; its two nibbles summed (16 = 1 mod 3): <= 30
        andlw   0x0F
        movwf   ACC1
        movf    ACC0, W
        andlw   0x0F
        addwf   ACC1, F
        movlw   3
jm_three:                               ; ACC1 = y mod 3
        subwf   ACC1, F
        btfsc   STATUS, C
        goto    jm_three
        addwf   ACC1, F
        swapf   ACC1, F                 ; 32 (y mod 3) + (x mod 32)
        bcf     STATUS, C
        rlf     ACC1, W
        iorwf   TMP0, W
        return

; jr_bytes: send W bytes from FSR on, each into the CRC (COUNT)
jr_bytes:
        movwf   COUNT
jb_next:
        movf    INDF, W
        call    jr_byte
        incf    FSR, F
        decfsz  COUNT, F
        goto    jb_next
        return

; jr_byte: W into the CRC-16/XMODEM (x = crc_h ^ b, x ^= x >> 4; crc = crc << 8 ^ x << 12 ^ x << 5 ^ x), then
; sent. R = x rotated right by 3 gives x >> 3 (R & 0x1F) and x << 5 (R & 0xE0).
jr_byte:
        movwf   TMP0
        xorwf   JR_CRC_H, W
        movwf   JR_X
        swapf   JR_X, W
        andlw   0x0F
        xorwf   JR_X, F                 ; x ^= x >> 4
        swapf   JR_X, W
        movwf   TMP2                    ; (the address is sent: TMP2 is free) x rotated by 4
        rlf     TMP2, W
        rlf     TMP2, F                 ; R = x rotated right by 3
        swapf   JR_X, W
        andlw   0xF0
        xorwf   JR_CRC_L, W
        movwf   JR_CRC_H                ; crc_h = crc_l ^ (x << 4)
        movf    TMP2, W
        andlw   0x1F
        xorwf   JR_CRC_H, F             ;   ^ (x >> 3)
        movf    TMP2, W
        andlw   0xE0
        xorwf   JR_X, W
        movwf   JR_CRC_L                ; crc_l = (x << 5) ^ x
        movf    TMP0, W
;       fall through: send it

; jr_tx: send W, wait for the acknowledge slot (step_record.asm's i2c_tx); returns in bank 0
jr_tx:
        bcf     STATUS, RP0
        bcf     STATUS, RP1
        movwf   SSPBUF
        I2C_WAIT
        return

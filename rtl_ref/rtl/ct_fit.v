// ct_fit: put an exact signed integer into a register, with the model's overflow modes
// (chiptwin.dsp.fmt.fit_int, chiptwin.dsp._kernels._fit).
//
//   OMODE 0 WRAP     keep the low OW bits (two's complement modulo 2^OW); wrap = value changed
//   OMODE 1 SAT      clamp to [lo, hi]; sat = value changed
//   OMODE 2 SAT_SYM  signed register: clamp to [-hi, hi], the most negative code never leaves
//                    (it becomes -hi and counts as a saturation); unsigned register: SAT
//
// lo/hi: signed -2^(OW-1) / 2^(OW-1)-1, unsigned 0 / 2^OW-1. Combinational.
`default_nettype none

module ct_fit #(
    parameter integer IW = 17,       // input width, signed two's complement
    parameter integer OW = 16,       // register width
    parameter integer OSIGNED = 1,   // 1 two's complement register, 0 unsigned register
    parameter integer OMODE = 1      // 0 WRAP, 1 SAT, 2 SAT_SYM
) (
    input  wire [IW-1:0] x,          // signed
    output wire [OW-1:0] y,
    output wire          sat,
    output wire          wrap
);
    // EW > max(IW, OW): both the input and the register range are representable
    localparam integer EW = (IW > OW ? IW : OW) + 1;
    localparam [OW-1:0] ONES = {OW{1'b1}};
    localparam [OW-1:0] HI = (OSIGNED != 0) ? (ONES >> 1) : ONES;
    localparam [OW-1:0] LO = (OSIGNED != 0) ? ~HI : {OW{1'b0}};
    localparam [OW-1:0] SYM_LO = LO + {{(OW - 1){1'b0}}, 1'b1};  // -hi (signed only)

    wire [EW-1:0] xe;
    ct_ext #(.IW(IW), .OW(EW), .SIGNED(1)) u_ext (.x(x), .y(xe));

    wire fits;
    generate
        if (OSIGNED != 0) begin : g_signed
            wire [EW-OW:0] top = xe[EW-1:OW-1];   // sign copies when the value fits
            assign fits = (&top) | ~(|top);
        end else begin : g_unsigned
            wire [EW-OW-1:0] top = xe[EW-1:OW];   // zero when the value fits (sign included)
            assign fits = ~(|top);
        end
    endgenerate

    wire [OW-1:0] low = xe[OW-1:0];
    generate
        if (OMODE == 0) begin : g_wrap
            assign y = low;
            assign sat = 1'b0;
            assign wrap = ~fits;
        end else if (OMODE == 2 && OSIGNED != 0) begin : g_sat_sym
            wire neg = xe[EW-1];
            wire is_min = fits & (low == LO);
            assign y = (fits & ~is_min) ? low : (neg ? SYM_LO : HI);
            assign sat = ~fits | is_min;
            assign wrap = 1'b0;
        end else begin : g_sat
            wire neg = xe[EW-1];
            assign y = fits ? low : (neg ? LO : HI);
            assign sat = ~fits;
            assign wrap = 1'b0;
        end
    endgenerate
endmodule

`default_nettype wire

// ct_requant: move a signed code from FRAC_IN to FRAC_OUT = FRAC_IN - SH fractional bits:
// round away SH bits (SH > 0) or shift left (SH < 0), then fit the register
// (chiptwin.dsp.fixed.requantize: one rounding, then overflow). Combinational.
//
// RMODE (chiptwin.dsp.fmt.ROUNDING_MODES): 0 TRN floor, 1 TRN_ZERO toward zero,
// 2 RND ties -> +inf, 3 RND_ZERO ties -> 0, 4 RND_INF ties away from 0, 5 RND_CONV ties to even.
// With q = floor(x / 2^SH) and r = x - q 2^SH the increment is (as _kernels._inc):
//   above = r > 2^(SH-1), tie = r == 2^(SH-1), inexact = r != 0, neg = x < 0, odd = q[0].
//
// `CT_MUTANT_ROUND (harness self-test only): ties are treated as below half, i.e. the
// rounding constant 2^(SH-1) becomes 2^(SH-1) - 1 for the round-to-nearest modes.
`default_nettype none

module ct_requant #(
    parameter integer IW = 20,       // input width, signed
    parameter integer SH = 2,        // fractional bits dropped (negative: appended)
    parameter integer RMODE = 5,
    parameter integer OW = 16,
    parameter integer OSIGNED = 1,
    parameter integer OMODE = 1
) (
    input  wire [IW-1:0] x,          // signed
    output wire [OW-1:0] y,
    output wire          sat,
    output wire          wrap
);
    generate
        if (SH > 0) begin : g_round
            localparam integer XW = (IW > SH) ? IW : SH + 1;   // holds x and its SH low bits
            localparam integer QW = XW - SH;                  // floor(x / 2^SH), >= 1 bit
            wire [XW-1:0] xe;
            ct_ext #(.IW(IW), .OW(XW), .SIGNED(1)) u_ext (.x(x), .y(xe));
            wire [QW-1:0] q = xe[XW-1:SH];
            wire [SH-1:0] r = xe[SH-1:0];
            wire half = r[SH-1];
            wire below_half_nonzero;
            if (SH > 1) begin : g_low
                assign below_half_nonzero = |r[SH-2:0];
            end else begin : g_nolow
                assign below_half_nonzero = 1'b0;
            end
            wire neg = xe[XW-1];
`ifdef CT_MUTANT_ROUND
            wire above = half & below_half_nonzero;
            wire tie = 1'b0;
`else
            wire above = half & below_half_nonzero;
            wire tie = half & ~below_half_nonzero;
`endif
            wire inexact = |r;
            wire odd = q[0];
            wire inc = (RMODE == 0) ? 1'b0
                     : (RMODE == 1) ? (inexact & neg)
                     : (RMODE == 2) ? (above | tie)
                     : (RMODE == 3) ? (above | (tie & neg))
                     : (RMODE == 4) ? (above | (tie & ~neg))
                     : (above | (tie & odd));
            wire [QW:0] qe;
            ct_ext #(.IW(QW), .OW(QW + 1), .SIGNED(1)) u_qext (.x(q), .y(qe));
            wire [QW:0] rounded = qe + {{QW{1'b0}}, inc};
            ct_fit #(.IW(QW + 1), .OW(OW), .OSIGNED(OSIGNED), .OMODE(OMODE)) u_fit (
                .x(rounded), .y(y), .sat(sat), .wrap(wrap)
            );
        end else if (SH == 0) begin : g_same
            ct_fit #(.IW(IW), .OW(OW), .OSIGNED(OSIGNED), .OMODE(OMODE)) u_fit (
                .x(x), .y(y), .sat(sat), .wrap(wrap)
            );
        end else begin : g_shl
            wire [IW-SH-1:0] xs = {x, {(-SH){1'b0}}};
            ct_fit #(.IW(IW - SH), .OW(OW), .OSIGNED(OSIGNED), .OMODE(OMODE)) u_fit (
                .x(xs), .y(y), .sat(sat), .wrap(wrap)
            );
        end
    endgenerate
endmodule

`default_nettype wire

// ct_divide: value / N into the output register, one rounding (chiptwin.dsp.registers.divide).
//
// N a power of two: the value's codes read with log2 N more fractional bits (a wire shift).
// Otherwise: the full-precision product value * RECIP, RECIP = 1/N rounded to nearest even in
// an unsigned RECIP_W-bit register with RECIP_F = RECIP_W + floor(log2 N) fractional bits
// (registers.reciprocal_code; the generator computes the constant). Then requantize to the
// output register (RMODE, OMODE). Combinational.
`default_nettype none

module ct_divide #(
    parameter integer IW = 20,          // value width, signed
    parameter integer IN_F = 2,         // value fractional bits
    parameter integer N = 4,
    parameter integer RECIP_W = 18,
    parameter integer RECIP_F = 19,
    parameter [63:0]  RECIP = 64'd0,    // used when N is not a power of two
    parameter integer OUT_W = 16, parameter integer OUT_F = 2, parameter integer OUT_S = 1,
    parameter integer RMODE = 5,
    parameter integer OMODE = 1
) (
    input  wire [IW-1:0]    x,          // signed
    output wire [OUT_W-1:0] y,
    output wire             sat,
    output wire             wrap
);
    localparam integer POW2 = ((N & (N - 1)) == 0) ? 1 : 0;
    localparam integer LOG2N = $clog2(N);
    generate
        if (POW2 != 0) begin : g_shift
            ct_requant #(
                .IW(IW), .SH(IN_F + LOG2N - OUT_F), .RMODE(RMODE),
                .OW(OUT_W), .OSIGNED(OUT_S), .OMODE(OMODE)
            ) u_out (.x(x), .y(y), .sat(sat), .wrap(wrap));
        end else begin : g_recip
            localparam integer PW = IW + RECIP_W + 1;
            localparam [RECIP_W:0] R = {1'b0, RECIP[RECIP_W-1:0]};
            wire [PW-1:0] xe, re;
            ct_ext #(.IW(IW), .OW(PW), .SIGNED(1)) u_xe (.x(x), .y(xe));
            ct_ext #(.IW(RECIP_W + 1), .OW(PW), .SIGNED(1)) u_re (.x(R), .y(re));
            wire [PW-1:0] product = xe * re;      // exact: |x| * RECIP < 2^(PW-1)
            ct_requant #(
                .IW(PW), .SH(IN_F + RECIP_F - OUT_F), .RMODE(RMODE),
                .OW(OUT_W), .OSIGNED(OUT_S), .OMODE(OMODE)
            ) u_out (.x(product), .y(y), .sat(sat), .wrap(wrap));
        end
    endgenerate
endmodule

`default_nettype wire

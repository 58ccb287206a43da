// ct_addfit: one accumulator update, acc + term exactly, then fit the accumulator register
// (chiptwin.dsp._kernels._add_fit). Combinational.
`default_nettype none

module ct_addfit #(
    parameter integer AW = 18, parameter integer AS = 1,   // accumulator register
    parameter integer TW = 16, parameter integer TS = 1,   // term (same fractional bits)
    parameter integer OMODE = 0                            // 0 WRAP, 1 SAT, 2 SAT_SYM
) (
    input  wire [AW-1:0] acc,
    input  wire [TW-1:0] term,
    output wire [AW-1:0] y,
    output wire          sat,
    output wire          wrap
);
    localparam integer AV = AW + (AS != 0 ? 0 : 1);
    localparam integer TV = TW + (TS != 0 ? 0 : 1);
    localparam integer SW = (AV > TV ? AV : TV) + 1;
    wire [SW-1:0] a, t;
    ct_ext #(.IW(AW), .OW(SW), .SIGNED(AS)) u_a (.x(acc), .y(a));
    ct_ext #(.IW(TW), .OW(SW), .SIGNED(TS)) u_t (.x(term), .y(t));
    wire [SW-1:0] sum = a + t;
    ct_fit #(.IW(SW), .OW(AW), .OSIGNED(AS), .OMODE(OMODE)) u_fit (
        .x(sum), .y(y), .sat(sat), .wrap(wrap)
    );
endmodule

`default_nettype wire

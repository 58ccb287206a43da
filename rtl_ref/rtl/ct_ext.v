// ct_ext: widen an IW-bit code to OW >= IW bits, by sign extension (SIGNED = 1) or zero
// extension (SIGNED = 0). Pure wiring; the one place the RTL changes a word's width upward.
`default_nettype none

module ct_ext #(
    parameter integer IW = 8,
    parameter integer OW = 9,
    parameter integer SIGNED = 1
) (
    input  wire [IW-1:0] x,
    output wire [OW-1:0] y
);
    generate
        if (OW > IW) begin : g_ext
            wire fill = (SIGNED != 0) ? x[IW-1] : 1'b0;
            assign y = {{(OW - IW){fill}}, x};
        end else begin : g_same
            assign y = x;
        end
    endgenerate
endmodule

`default_nettype wire

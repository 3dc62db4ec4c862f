!> The force kernel's copies between the state and a chunk's node rows (iem_cell_kernel's
!> cell_forces): the rows' values gathered out of the state, and the chunk's corner forces
!> added to its nodes' forces, each node's in cell order. Consecutively numbered rows are
!> copied with AVX2 vectors where built (iem_kernel_rows_simd.c, through iem_kernel_simd),
!> bit for bit these loops.
module iem_kernel_rows
  use iem_kinds, only: wp
  use iem_cell_laws, only: chunk
  use iem_kernel_simd, only: kernel_simd, c_gather_row4, c_scatter_rows
  implicit none
  private
  public :: gather_block, gather_row, gather_rows, gather_filtered, add_node_forces
  public :: add_routed_forces
  public :: add_block_forces, set_aside

contains

  !> Rows r, r+1 of y at the nodes b0..b0+m (bottom) and t0..t0+m (top) into wb, wt(0:m, 2).
  pure subroutine gather_block(y, r, m, b0, t0, wb, wt)
    real(wp), intent(in), contiguous :: y(:, :)
    integer, intent(in) :: r, m, b0, t0
    real(wp), intent(inout) :: wb(0:chunk, 2), wt(0:chunk, 2)
    call gather_row(y, r, m, b0, wb)
    call gather_row(y, r, m, t0, wt)
  end subroutine gather_block

  !> Rows r, r+1 of y at the nodes n0..n0+m into w(0:m, 2).
  pure subroutine gather_row(y, r, m, n0, w)
    real(wp), intent(in), contiguous :: y(:, :)
    integer, intent(in) :: r, m, n0
    real(wp), intent(inout) :: w(0:chunk, 2)
    if (size(y, 1) == 4 .and. kernel_simd()) then
      call c_gather_row4(m, y(:, n0:n0 + m), r - 1, chunk + 1, w)
    else if (size(y, 1) == 4) then
      call block_row(4, y(:, n0:n0 + m), w)
    else
      call block_row(size(y, 1), y(:, n0:n0 + m), w)
    end if
  contains

    !> The two rows from a block of consecutive nodes (ns values a node).
    pure subroutine block_row(ns, yb, v)
      integer, intent(in) :: ns
      real(wp), intent(in) :: yb(ns, 0:m)
      real(wp), intent(inout) :: v(0:chunk, 2)
      integer :: i
      do i = 0, m
        v(i, 1) = yb(r, i)
        v(i, 2) = yb(r + 1, i)
      end do
    end subroutine block_row
  end subroutine gather_row

  !> A chunk's rows of a state of 6 values a node (capped damping), the nodes b0..b0+m
  !> (bottom) and t0..t0+m (top) read once: the displacements (rows 1, 2) into ub (only with
  !> bottom) and ut, the filtered velocities (5, 6) into wb, wt, the velocities (3, 4) into
  !> vb, vt (each (0:m, 2)): gather_row's and gather_block's copies in one pass.
  pure subroutine gather_filtered(y, m, b0, t0, bottom, ub, ut, wb, wt, vb, vt)
    real(wp), intent(in), contiguous :: y(:, :)
    integer, intent(in) :: m, b0, t0
    logical, intent(in) :: bottom
    real(wp), intent(inout) :: ub(0:chunk, 2), ut(0:chunk, 2), wb(0:chunk, 2), wt(0:chunk, 2)
    real(wp), intent(inout) :: vb(0:chunk, 2), vt(0:chunk, 2)
    integer :: i
    if (bottom) then
      do i = 0, m
        ub(i, 1) = y(1, b0 + i)
        ub(i, 2) = y(2, b0 + i)
      end do
    end if
    do i = 0, m
      vb(i, 1) = y(3, b0 + i)
      vb(i, 2) = y(4, b0 + i)
      wb(i, 1) = y(5, b0 + i)
      wb(i, 2) = y(6, b0 + i)
    end do
    do i = 0, m
      ut(i, 1) = y(1, t0 + i)
      ut(i, 2) = y(2, t0 + i)
      vt(i, 1) = y(3, t0 + i)
      vt(i, 2) = y(4, t0 + i)
      wt(i, 1) = y(5, t0 + i)
      wt(i, 2) = y(6, t0 + i)
    end do
  end subroutine gather_filtered

  !> Rows r, r+1 of y at the chunk's bottom and top nodes bn(0:m), tn(0:m) into wb, wt(0:m, 2).
  pure subroutine gather_rows(y, r, m, bn, tn, wb, wt)
    real(wp), intent(in), contiguous :: y(:, :)
    integer, intent(in) :: r, m, bn(0:chunk), tn(0:chunk)
    real(wp), intent(inout) :: wb(0:chunk, 2), wt(0:chunk, 2)
    integer :: i
    do i = 0, m
      wb(i, 1) = y(r, bn(i))
      wb(i, 2) = y(r + 1, bn(i))
      wt(i, 1) = y(r, tn(i))
      wt(i, 2) = y(r + 1, tn(i))
    end do
  end subroutine gather_rows

  !> Add the corner forces fx, fy(cell, corner) of a chunk to its nodes' forces f, each node's
  !> in cell order: bottom node i gets corner 2 of cell i, then corner 1 of cell i + 1; top
  !> node i corner 3 of cell i, then corner 4 of cell i + 1.
  pure subroutine add_node_forces(m, bn, tn, fx, fy, f)
    integer, intent(in) :: m, bn(0:chunk), tn(0:chunk)
    real(wp), intent(in) :: fx(chunk, 4), fy(chunk, 4)
    real(wp), intent(inout), contiguous :: f(:, :)
    integer :: i
    f(1, bn(0)) = f(1, bn(0)) + fx(1, 1)
    f(2, bn(0)) = f(2, bn(0)) + fy(1, 1)
    f(1, tn(0)) = f(1, tn(0)) + fx(1, 4)
    f(2, tn(0)) = f(2, tn(0)) + fy(1, 4)
    do i = 1, m - 1
      f(1, bn(i)) = f(1, bn(i)) + fx(i, 2) + fx(i + 1, 1)
      f(2, bn(i)) = f(2, bn(i)) + fy(i, 2) + fy(i + 1, 1)
      f(1, tn(i)) = f(1, tn(i)) + fx(i, 3) + fx(i + 1, 4)
      f(2, tn(i)) = f(2, tn(i)) + fy(i, 3) + fy(i + 1, 4)
    end do
    f(1, bn(m)) = f(1, bn(m)) + fx(m, 2)
    f(2, bn(m)) = f(2, bn(m)) + fy(m, 2)
    f(1, tn(m)) = f(1, tn(m)) + fx(m, 3)
    f(2, tn(m)) = f(2, tn(m)) + fy(m, 3)
  end subroutine add_node_forces

  !> Route the corner forces fx, fy(cell, corner) of a chunk's m cells (corners cn(:, 1:m)):
  !> corner q of cell i by rt(4*(i - 1) + q): 0 added to its node's force in f, r > 0 stored
  !> in side(:, r), < 0 dropped. Each node's additions to f come in cell order.
  pure subroutine add_routed_forces(m, cn, rt, fx, fy, f, side)
    integer, intent(in) :: m, cn(:, :), rt(:)
    real(wp), intent(in) :: fx(chunk, 4), fy(chunk, 4)
    real(wp), intent(inout), contiguous :: f(:, :), side(:, :)
    integer :: i, q, r, n
    do i = 1, m
      do q = 1, 4
        r = rt(4*(i - 1) + q)
        if (r == 0) then
          n = cn(q, i)
          f(1, n) = f(1, n) + fx(i, q)
          f(2, n) = f(2, n) + fy(i, q)
        else if (r > 0) then
          side(1, r) = fx(i, q)
          side(2, r) = fy(i, q)
        end if
      end do
    end do
  end subroutine add_routed_forces

  !> The corner forces that a chunk's list ex sets aside stored in their side slots and
  !> cleared in fx, fy (so that adding the chunk's forces adds +0 for them): ex(1) = n, then
  !> n pairs (4*(i - 1) + q, r): corner q of cell i to side(:, r).
  pure subroutine set_aside(ex, fx, fy, side)
    integer, intent(in) :: ex(:)
    real(wp), intent(inout) :: fx(chunk, 4), fy(chunk, 4)
    real(wp), intent(inout), contiguous :: side(:, :)
    integer :: e, i, q, r
    do e = 1, ex(1)
      i = (ex(2*e) - 1)/4 + 1
      q = ex(2*e) - 4*(i - 1)
      r = ex(2*e + 1)
      side(1, r) = fx(i, q)
      side(2, r) = fy(i, q)
      fx(i, q) = 0.0_wp
      fy(i, q) = 0.0_wp
    end do
  end subroutine set_aside

  !> add_node_forces for consecutively numbered node rows: the forces fb, ft of the bottom
  !> and top rows' nodes 0..m.
  pure subroutine add_block_forces(m, fb, ft, fx, fy)
    integer, intent(in) :: m
    real(wp), intent(inout) :: fb(2, 0:m), ft(2, 0:m)
    real(wp), intent(in) :: fx(chunk, 4), fy(chunk, 4)
    integer :: j
    if (kernel_simd()) then
      call c_scatter_rows(m, fb, ft, fx, fy, chunk)
      return
    end if
    fb(1, 0) = fb(1, 0) + fx(1, 1)
    fb(2, 0) = fb(2, 0) + fy(1, 1)
    ft(1, 0) = ft(1, 0) + fx(1, 4)
    ft(2, 0) = ft(2, 0) + fy(1, 4)
    do j = 1, m - 1
      fb(1, j) = fb(1, j) + fx(j, 2) + fx(j + 1, 1)
      fb(2, j) = fb(2, j) + fy(j, 2) + fy(j + 1, 1)
      ft(1, j) = ft(1, j) + fx(j, 3) + fx(j + 1, 4)
      ft(2, j) = ft(2, j) + fy(j, 3) + fy(j + 1, 4)
    end do
    fb(1, m) = fb(1, m) + fx(m, 2)
    fb(2, m) = fb(2, m) + fy(m, 2)
    ft(1, m) = ft(1, m) + fx(m, 3)
    ft(2, m) = ft(2, m) + fy(m, 3)
  end subroutine add_block_forces
end module iem_kernel_rows

!> The force kernel's elastic cells (iem_cell_chunk measures a chunk's edges first): each
!> cell's strains, law, damping stresses and corner forces in one branch-free loop over the
!> chunk that keeps every intermediate in registers. The loop body lives in
!> elastic_loop/*.inc, shared by the variants here: what each keeps besides the forces
!> (energies and strains, or fracture's onset count: of every criterion (_lean) or of shear
!> alone (_shear)), a law per cell with damping stresses or one law without (_plain), and the
!> paper's cell without its law's zero terms (_paper).
module iem_cell_elastic
  use iem_kinds, only: wp, i8
  use iem_spring_constants, only: cell_constants_t
  use iem_cell_laws, only: chunk
  use iem_cell_chunk, only: edge_row_t, edge_col_t
  implicit none
  private
  public :: chunk_elastic, chunk_elastic_forces, chunk_elastic_plain, chunk_elastic_paper, &
            chunk_elastic_plain_energy, chunk_elastic_plain_lean, chunk_elastic_paper_lean, &
            chunk_elastic_lean, chunk_elastic_tested
  public :: onsets_none, onsets_shear, onsets_all

  !> Which of fracture's onsets a chunk's elastic loop counts: none (the loops without a
  !> test), the shear onset alone, every criterion's (chunk_elastic_tested's two).
  integer, parameter :: onsets_none = 0, onsets_shear = 1, onsets_all = 2

contains

  !> The corner forces fx, fy of a chunk's elastic cells without their energies, in the loop
  !> that counts in n_past the cells past the onsets on(3) of test (onsets_shear: on(3)
  !> alone; onsets_all: every criterion): with a law per cell lc and damping stresses hd, ud
  !> (general), else of one law lc1 (paper: the paper's cell).
  pure subroutine chunk_elastic_tested(k, m, bot, top, v, general, paper, lc, hd, ud, lc1, &
                                       test, on, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m, test
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    logical, intent(in) :: general, paper
    real(wp), intent(in) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4), lc1(5), on(3)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    if (test == onsets_shear) then
      if (general) then
        call chunk_elastic_shear(k, m, bot, top, v, lc, hd, ud, on(3), fx, fy, n_past)
      else if (paper) then
        call chunk_elastic_paper_shear(k, m, bot, top, v, lc1, on(3), fx, fy, n_past)
      else
        call chunk_elastic_plain_shear(k, m, bot, top, v, lc1, on(3), fx, fy, n_past)
      end if
    else
      if (general) then
        call chunk_elastic_lean(k, m, bot, top, v, lc, hd, ud, on, fx, fy, n_past)
      else if (paper) then
        call chunk_elastic_paper_lean(k, m, bot, top, v, lc1, on, fx, fy, n_past)
      else
        call chunk_elastic_plain_lean(k, m, bot, top, v, lc1, on, fx, fy, n_past)
      end if
    end if
  end subroutine chunk_elastic_tested

  !> The elastic cells of a chunk in one loop: per cell its shear measures, its law (the
  !> coefficients lc(cell, :) of law_coefficients), the damping stresses hd, ud (0 when not
  !> damped), the corner forces fx, fy(cell, corner) and the strain energy en; the edge
  !> strains ep and shear measures s are kept (for fracture's test).
  pure subroutine chunk_elastic(k, m, bot, top, v, lc, hd, ud, fx, fy, en, ep, s)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4), en(chunk)
    real(wp), intent(out) :: ep(chunk, 4), s(chunk, 4)
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_cell_law.inc'
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_energy.inc'
      include 'elastic_loop/iem_cell_elastic_damped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic

  !> chunk_elastic's corner forces fx, fy alone (no energies, strains or shear measures kept).
  pure subroutine chunk_elastic_forces(k, m, bot, top, v, lc, hd, ud, fx, fy)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    ilx = k%il0(1)
    ily = k%il0(2)
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_cell_law.inc'
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_damped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_forces

  !> chunk_elastic_plain for the paper's cell (lc1(3) = lc1(5) = 0): the same forces.
  pure subroutine chunk_elastic_paper(k, m, bot, top, v, lc1, fx, fy)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law_paper.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_paper

  !> chunk_elastic_forces for cells of one law (coefficients lc1) without damping.
  pure subroutine chunk_elastic_plain(k, m, bot, top, v, lc1, fx, fy)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_plain

  !> chunk_elastic for cells of one law (coefficients lc1) without damping: the corner forces,
  !> each cell's strain energy en, edge strains ep and shear measures s.
  pure subroutine chunk_elastic_plain_energy(k, m, bot, top, v, lc1, fx, fy, en, ep, s)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4), en(chunk)
    real(wp), intent(out) :: ep(chunk, 4), s(chunk, 4)
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_energy.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_plain_energy

  !> chunk_elastic_lean for cells of one law (coefficients lc1) without damping.
  pure subroutine chunk_elastic_plain_lean(k, m, bot, top, v, lc1, on, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5), on(3)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'
    real(wp) :: on_t, on_c, on_s

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    on_t = on(1)
    on_c = on(2)
    on_s = on(3)
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_onsets.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_plain_lean

  !> chunk_elastic_plain_lean for the paper's cell (lc1(3) = lc1(5) = 0), as
  !> chunk_elastic_paper: the same forces and count.
  pure subroutine chunk_elastic_paper_lean(k, m, bot, top, v, lc1, on, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5), on(3)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'
    real(wp) :: on_t, on_c, on_s

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    on_t = on(1)
    on_c = on(2)
    on_s = on(3)
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law_paper.inc'
      include 'elastic_loop/iem_cell_elastic_onsets.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_paper_lean

  !> chunk_elastic_forces with n_past, not 0 when a cell has a strain past the onsets on(3)
  !> (tension: eps > on(1); crushing: -eps > on(2); shear: |s| > on(3)): for fracture's test
  !> of an intact chunk (it counts, per cell, the criteria passed).
  pure subroutine chunk_elastic_lean(k, m, bot, top, v, lc, hd, ud, on, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4), on(3)
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'
    real(wp) :: on_t, on_c, on_s

    ilx = k%il0(1)
    ily = k%il0(2)
    on_t = on(1)
    on_c = on(2)
    on_s = on(3)
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_cell_law.inc'
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_onsets.inc'
      include 'elastic_loop/iem_cell_elastic_damped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
    end do
  end subroutine chunk_elastic_lean

  !> chunk_elastic_lean counting the shear criterion alone (n_past not 0 when a cell has
  !> |s| > on_s): for a chunk whose edges chunk_edges found clear of the other onsets.
  pure subroutine chunk_elastic_shear(k, m, bot, top, v, lc, hd, ud, on_s, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc(chunk, 5), hd(chunk, 4), ud(chunk, 4), on_s
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    ilx = k%il0(1)
    ily = k%il0(2)
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_cell_law.inc'
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_damped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
      include 'elastic_loop/iem_cell_elastic_shear_onset.inc'
    end do
  end subroutine chunk_elastic_shear

  !> chunk_elastic_shear for cells of one law (coefficients lc1) without damping.
  pure subroutine chunk_elastic_plain_shear(k, m, bot, top, v, lc1, on_s, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5), on_s
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
      include 'elastic_loop/iem_cell_elastic_shear_onset.inc'
    end do
  end subroutine chunk_elastic_plain_shear

  !> chunk_elastic_plain_shear for the paper's cell (lc1(3) = lc1(5) = 0), as
  !> chunk_elastic_paper: the same forces and count.
  pure subroutine chunk_elastic_paper_shear(k, m, bot, top, v, lc1, on_s, fx, fy, n_past)
    type(cell_constants_t), intent(in) :: k
    integer, intent(in) :: m
    type(edge_row_t), intent(in) :: bot, top
    type(edge_col_t), intent(in) :: v
    real(wp), intent(in) :: lc1(5), on_s
    real(wp), intent(out) :: fx(chunk, 4), fy(chunk, 4)
    integer(i8), intent(out) :: n_past
    include 'elastic_loop/iem_cell_elastic_locals.inc'

    include 'elastic_loop/iem_cell_elastic_one_law.inc'
    n_past = 0
    do c = 1, m
      include 'elastic_loop/iem_cell_elastic_strains.inc'
      include 'elastic_loop/iem_cell_elastic_law_paper.inc'
      include 'elastic_loop/iem_cell_elastic_undamped.inc'
      include 'elastic_loop/iem_cell_elastic_forces.inc'
      include 'elastic_loop/iem_cell_elastic_shear_onset.inc'
    end do
  end subroutine chunk_elastic_paper_shear
end module iem_cell_elastic

!> The body: a background grid of rectangular cells, each cell void or of one material, from
!> the background material, an image cell map and shapes (later ones win; a cell takes what
!> holds its centre). This type is the body's description, small on every rank: it classifies
!> the cells of any band of grid rows on demand (classify_rows) and never holds a map of the
!> whole grid. Cells and the nodes they use are numbered row by row (iem_body_numbering); a
!> full rectangle (uniform) keeps the grid's numbers.
module iem_body
  use, intrinsic :: iso_fortran_env, only: int8
  use iem_kinds, only: wp, i8
  use iem_grid, only: grid_t
  use iem_shapes, only: shape_t, shape_rectangle, shape_circle, shape_polygon, shape_contains
  use iem_config, only: config_t
  use iem_image, only: image_t, read_image_rows
  use iem_strings, only: itoa
  implicit none
  private
  public :: body_t, max_materials

  !> Most materials a body may have (a cell's material is kept in one byte).
  integer, parameter :: max_materials = 100

  !> The body's description and, once numbered, its totals.
  type :: body_t
    type(grid_t) :: grid
    integer :: n_materials = 1
    !> Material of the grid before the image and the shapes (0: void).
    integer :: background = 1
    type(shape_t), allocatable :: shapes(:)
    !> The crack shapes (material = 'crack'), in file order; their places in shapes hold a
    !> shape that contains nothing, so that shape numbers stay those of the file.
    type(shape_t), allocatable :: cracks(:)
    !> Cell map image ('' none), its grey levels and the material of each (0: void).
    character(len=:), allocatable :: image
    integer, allocatable :: image_levels(:), image_ids(:)
    !> True when every cell of the grid is of the background material (no image, no shape):
    !> cell and node numbers are then the grid's.
    logical :: uniform = .true.
    !> Cells and nodes of the body, cells of each material, and its pieces (cells joined
    !> through shared nodes) with the centres of a cell of each but the largest (up to 5).
    integer(i8) :: n_nodes = 0, n_cells = 0
    integer(i8), allocatable :: material_cells(:)
    integer(i8) :: n_pieces = 1
    integer :: n_listed = 0
    !> Cells before cell row j (0:ny) and nodes before node row j (0:ny+1): the grid's for a
    !> full rectangle, from iem_body_numbering otherwise; the only arrays over the grid (one
    !> number a row).
    integer(i8), allocatable :: cell_first(:), node_first(:)
    real(wp) :: piece_xy(2, 5) = 0.0_wp
  contains
    procedure :: init => body_init
    procedure :: classify_rows => body_classify_rows
    procedure :: free => body_free
  end type body_t

contains

  !> Take the body's description from the configuration: grid, materials, shapes, image.
  !> A full rectangle is numbered at once; other bodies by iem_body_numbering (collective).
  !> stat /= 0 with msg for a rectangle of background 'void' (an empty body).
  subroutine body_init(this, cfg, grid, stat, msg)
    class(body_t), intent(inout) :: this
    type(config_t), intent(in) :: cfg
    type(grid_t), intent(in) :: grid
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    integer :: k, n

    call this%free()
    stat = 0
    msg = ''
    this%grid = grid
    this%n_materials = size(cfg%materials)
    this%background = cfg%geometry%background_id
    allocate(this%shapes(size(cfg%shapes)), this%cracks(count(cfg%shapes(:)%crack)))
    n = 0
    do k = 1, size(cfg%shapes)
      associate(s => cfg%shapes(k))
        select case (trim(s%kind))
        case ('rectangle')
          this%shapes(k) = shape_rectangle(s%box(1), s%box(2), s%box(3), s%box(4), s%material_id)
        case ('circle')
          this%shapes(k) = shape_circle(s%center(1), s%center(2), s%radius, s%material_id)
        case default
          this%shapes(k) = shape_polygon(s%points, s%material_id)
        end select
        if (s%crack) then
          n = n + 1
          this%cracks(n) = this%shapes(k)
          this%shapes(k) = shape_t()
        end if
      end associate
    end do
    this%image = trim(cfg%geometry%image)
    if (len(this%image) > 0) then
      this%image_levels = cfg%geometry%image_levels
      this%image_ids = cfg%geometry%image_material_ids
    end if
    this%uniform = size(this%shapes) == size(this%cracks) .and. len(this%image) == 0
    allocate(this%material_cells(this%n_materials))
    this%material_cells = 0
    if (this%uniform) then
      if (this%background == 0) then
        stat = 1
        msg = "&geometry: background = 'void' with no image and no &shape: the body is empty"
        return
      end if
      this%n_cells = grid%n_cells
      this%n_nodes = grid%n_nodes
      this%material_cells(this%background) = grid%n_cells
      allocate(this%cell_first(0:grid%ny), this%node_first(0:grid%ny + 1))
      do k = 0, grid%ny
        this%cell_first(k) = int(k, i8)*grid%nx
      end do
      do k = 0, grid%ny + 1
        this%node_first(k) = int(k, i8)*(grid%nx + 1)
      end do
    end if
  end subroutine body_init

  !> Material (0: void) and deciding shape (0: the background or the image; -1: outside the
  !> grid) of the grid cells of rows j0..j1 and columns i0..i1, which may reach outside the
  !> grid: mat(i0:i1, j0:j1), src(i0:i1, j0:j1). hits(k) counts the cells of rows h0..h1
  !> whose centre shape k holds; cells(m) the cells of material m in those rows. stat /= 0
  !> with msg (naming &geometry image) for an unreadable, mis-sized or unmatched image; the
  !> image's pixels are read only for the band's rows and columns (iem_image,
  !> read_image_rows).
  subroutine body_classify_rows(this, i0, i1, j0, j1, h0, h1, mat, src, hits, cells, stat, msg)
    class(body_t), intent(in) :: this
    integer, intent(in) :: i0, i1, j0, j1, h0, h1
    integer(int8), intent(out) :: mat(i0:, j0:), src(i0:, j0:)
    integer(i8), intent(out) :: hits(:), cells(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    type(image_t) :: img
    integer :: i, j, k, m, r, nx, ny
    real(wp) :: xc, yc

    stat = 0
    msg = ''
    hits = 0
    cells = 0
    nx = this%grid%nx
    ny = this%grid%ny
    ! the image's rows for the band: pixel (column c, row r) is cell (c - 1, ny - r)
    if (len(this%image) > 0 .and. max(j0, 0) <= min(j1, ny - 1)) then
      call read_image_rows(this%image, ny - min(j1, ny - 1), ny - max(j0, 0), img, stat, msg, &
                           max(i0, 0) + 1, min(i1, nx - 1) + 1)
      if (stat /= 0) then
        ! the reader names the file itself: keep only the reason
        if (index(msg, "image '"//this%image//"': ") == 1) msg = msg(len(this%image) + 11:)
        msg = "&geometry: image = '"//this%image//"': "//msg
        return
      end if
      if (img%width /= nx .or. img%height /= ny) then
        stat = 1
        msg = "&geometry: image = '"//this%image//"' is "//itoa(img%width)//' x '// &
              itoa(img%height)//' pixels but the grid has nx, ny = '//itoa(nx)//', '// &
              itoa(ny)//' cells (one pixel a cell)'
        return
      end if
    end if
    do j = j0, j1
      do i = i0, i1
        if (i < 0 .or. j < 0 .or. i >= nx .or. j >= ny) then
          mat(i, j) = 0
          src(i, j) = -1
          cycle
        end if
        m = this%background
        if (allocated(img%pix)) then
          r = ny - j
          k = findloc(this%image_levels, img%pix(i + 1, r), 1)
          if (k == 0) then
            stat = 1
            msg = '&geometry: image_levels has no entry for grey level '// &
                  itoa(img%pix(i + 1, r))//', the pixel at row '//itoa(r)//', column '// &
                  itoa(i + 1)//" of image = '"//this%image//"': every level of the image "// &
                  'needs a material'
            return
          end if
          m = this%image_ids(k)
        end if
        src(i, j) = 0
        xc = (i + 0.5_wp)*this%grid%lx
        yc = (j + 0.5_wp)*this%grid%ly
        do k = 1, size(this%shapes)
          if (shape_contains(this%shapes(k), xc, yc)) then
            if (j >= h0 .and. j <= h1) hits(k) = hits(k) + 1
            m = this%shapes(k)%material
            src(i, j) = int(k, int8)
          end if
        end do
        mat(i, j) = int(m, int8)
        if (m > 0 .and. j >= h0 .and. j <= h1) cells(m) = cells(m) + 1
      end do
    end do
  end subroutine body_classify_rows

  !> Release the description.
  subroutine body_free(this)
    class(body_t), intent(inout) :: this
    if (allocated(this%shapes)) deallocate(this%shapes)
    if (allocated(this%cracks)) deallocate(this%cracks)
    if (allocated(this%material_cells)) deallocate(this%material_cells)
    if (allocated(this%image_levels)) deallocate(this%image_levels)
    if (allocated(this%image_ids)) deallocate(this%image_ids)
    if (allocated(this%cell_first)) deallocate(this%cell_first)
    if (allocated(this%node_first)) deallocate(this%node_first)
    this%uniform = .true.
    this%n_nodes = 0
    this%n_cells = 0
    this%n_pieces = 1
    this%n_listed = 0
  end subroutine body_free
end module iem_body

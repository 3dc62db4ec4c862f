!> XDMF sidecar that lets ParaView open an iem HDF5 output file (see docs/output.md).
module iem_xdmf
  use iem_kinds, only: wp, i8
  use iem_strings, only: itoa
  implicit none
  private
  public :: xdmf_write, xdmf_frame_name, xdmf_path_of

contains

  !> Name of the HDF5 group of the frame with 0-based index `index`: frame_000000, ...
  pure function xdmf_frame_name(index) result(name)
    integer(i8), intent(in) :: index
    character(len=:), allocatable :: name
    character(len=32) :: buf

    write (buf, '(a, i0.6)') 'frame_', index
    name = trim(buf)
  end function xdmf_frame_name

  !> Path of the sidecar of `h5_path`: the extension of the file name replaced by `.xmf`.
  pure function xdmf_path_of(h5_path) result(xmf_path)
    character(len=*), intent(in) :: h5_path
    character(len=:), allocatable :: xmf_path
    integer :: dot, slash

    slash = index(h5_path, '/', back=.true.)
    dot = index(h5_path, '.', back=.true.)
    ! A dot in a folder name or a leading dot (hidden file) is no extension; a file already
    ! named .xmf keeps its name and gets a second extension, so the sidecar never replaces it.
    if (dot > slash + 1 .and. h5_path(dot:) /= '.xmf') then
      xmf_path = h5_path(:dot - 1)//'.xmf'
    else
      xmf_path = h5_path//'.xmf'
    end if
  end function xdmf_path_of

  !> Writes the sidecar: one grid per frame in a temporal collection, or the bare mesh.
  subroutine xdmf_write(xmf_path, h5_name, n_nodes, n_cells, times, stat, msg)
    ! h5_name: the HDF5 file as seen from the sidecar's folder; times(k): time of frame k-1.
    character(len=*), intent(in) :: xmf_path, h5_name
    integer(i8), intent(in) :: n_nodes, n_cells
    real(wp), intent(in) :: times(:)
    integer, intent(out) :: stat
    character(len=:), allocatable, intent(out) :: msg
    character(len=:), allocatable :: h5, dims_nodes, dims_cells, frame
    character(len=256) :: iom
    character(len=32) :: tbuf
    integer :: unit, k

    stat = 0
    msg = ''
    h5 = xml_escape(h5_name)
    dims_nodes = itoa(n_nodes)//' 2'
    dims_cells = itoa(n_cells)//' 4'
    open (newunit=unit, file=xmf_path, status='replace', action='write', form='formatted', &
          iostat=stat, iomsg=iom)
    if (stat /= 0) then
      msg = 'iem_xdmf: cannot open '//xmf_path//' for writing: '//trim(iom)
      return
    end if
    write (unit, '(a)', iostat=stat, iomsg=iom) '<?xml version="1.0" ?>', &
      '<Xdmf Version="3.0">', '  <Domain>'
    if (size(times) == 0) then
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) &
        '    <Grid Name="mesh" GridType="Uniform">'
      if (stat == 0) call write_mesh_items(unit, '      ', stat, iom)
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '    </Grid>'
    else
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) &
        '    <Grid Name="iem" GridType="Collection" CollectionType="Temporal">'
      do k = 1, size(times)
        if (stat /= 0) exit
        frame = xdmf_frame_name(int(k - 1, i8))
        write (tbuf, '(es24.16e3)') times(k)
        write (unit, '(a)', iostat=stat, iomsg=iom) &
          '      <Grid Name="'//frame//'" GridType="Uniform">', &
          '        <Time Value="'//trim(adjustl(tbuf))//'"/>'
        if (stat == 0) call write_mesh_items(unit, '        ', stat, iom)
        if (stat == 0) call write_vector(unit, 'displacement', frame, stat, iom)
        if (stat == 0) call write_vector(unit, 'velocity', frame, stat, iom)
        if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '      </Grid>'
      end do
      if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '    </Grid>'
    end if
    if (stat == 0) write (unit, '(a)', iostat=stat, iomsg=iom) '  </Domain>', '</Xdmf>'
    if (stat /= 0) then
      msg = 'iem_xdmf: cannot write '//xmf_path//': '//trim(iom)
      close (unit, iostat=k)
      return
    end if
    close (unit, iostat=stat, iomsg=iom)
    if (stat /= 0) msg = 'iem_xdmf: cannot close '//xmf_path//': '//trim(iom)

  contains

    !> Topology and geometry of the mesh, shared by every grid.
    subroutine write_mesh_items(u, ind, ios, iomsg)
      integer, intent(in) :: u
      character(len=*), intent(in) :: ind
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: iomsg

      write (u, '(a)', iostat=ios, iomsg=iomsg) &
        ind//'<Topology TopologyType="Quadrilateral" NumberOfElements="'//itoa(n_cells)//'">', &
        ind//'  <DataItem Dimensions="'//dims_cells//'" NumberType="Int" Precision="8" '// &
        'Format="HDF">'//h5//':/mesh/cells</DataItem>', &
        ind//'</Topology>', &
        ind//'<Geometry GeometryType="XY">', &
        ind//'  <DataItem Dimensions="'//dims_nodes//'" NumberType="Float" Precision="8" '// &
        'Format="HDF">'//h5//':/mesh/coordinates</DataItem>', &
        ind//'</Geometry>'
    end subroutine write_mesh_items

    !> One nodal vector field of a frame.
    subroutine write_vector(u, name, group, ios, iomsg)
      integer, intent(in) :: u
      character(len=*), intent(in) :: name, group
      integer, intent(out) :: ios
      character(len=*), intent(inout) :: iomsg

      write (u, '(a)', iostat=ios, iomsg=iomsg) &
        '        <Attribute Name="'//name//'" AttributeType="Vector" Center="Node">', &
        '          <DataItem Dimensions="'//dims_nodes//'" NumberType="Float" Precision="8" '// &
        'Format="HDF">'//h5//':/frames/'//group//'/'//name//'</DataItem>', &
        '        </Attribute>'
    end subroutine write_vector
  end subroutine xdmf_write


  !> `text` with the XML special characters replaced by entities.
  pure function xml_escape(text) result(s)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: s
    integer :: k

    s = ''
    do k = 1, len(text)
      select case (text(k:k))
      case ('&')
        s = s//'&amp;'
      case ('<')
        s = s//'&lt;'
      case ('>')
        s = s//'&gt;'
      case ('"')
        s = s//'&quot;'
      case default
        s = s//text(k:k)
      end select
    end do
  end function xml_escape
end module iem_xdmf
